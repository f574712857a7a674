"""Convolutional inpainting autoencoder for motion infilling (Kaufmann et al., "Convolutional Autoencoders
for Human Motion Infilling", 3DV 2020): a motion clip is an image of feature rows (body-frame joint
positions + root velocities) by frames; a fully convolutional AE fills gaps, removes noise and recovers
missing joints.  Baseline networks: the paper's Vanilla AE and a Holden-style 1D conv AE (``model.variant``).

config.py    presets paper / cpu / improved (default) / tiny: Config(model, data (incl. data.mask), loss, train)
features.py  motion <-> clip rows (facing yaw, root velocity integration), normaliser, clip bank
masks.py     training masks + gap curriculum (jnp), evaluation / inference masks and noise (NumPy)
model.py     init_params / apply (CAE, Vanilla AE, Holden 1D AE; optional residual over a linear or Hermite fill)
losses.py    L1 over the whole clip (gap-weighted with loss.gap_weight), L1 over the removed entries (logged)
train.py     load_data, make_training
infer.py     load(run), fill, process_motion (fill a user's motion, refit rotations), infill (CLI)
bench.py     the paper's Tables 1 / 2 + time-matched 1 s / 2 s / 4 s gaps (protocol: inbetween_jax.evaluation.infilling)
"""

INFILL_OPTIONS = {   # ``inbetween infill --model cae``: dest -> (metavar, help)
    "bvh": ("FILE.bvh", "the BVH file to fill"),
    "gaps": ("START:STOP[,...]", "frame ranges to fill (STOP exclusive); overlapping ranges are merged"),
}
