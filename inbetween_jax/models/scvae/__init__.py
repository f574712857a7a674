"""S-CVAE: "Diverse Motion In-betweening from Sparse Keyframes with Dual Posture Stitching" (Ren et al.).

Two adversarial autoregressive CVAE generators run forward from the start keyframe and backward from the
target keyframe, each conditioned on the other's latest frame (bi-directional aligning), with latent
interpolation between the current-frame and target-frame distributions and a phase-gated mixture-of-experts
decoder; the two halves are stitched over a 2K-frame buffer in the middle.  Given exactly two keyframes it
samples diverse transitions.

Files::

    config.py          Config(model, data, loss, train); PRESETS improved / improved-velocity / cpu / paper / tiny
    features.py        frames -> network inputs, feature statistics, TrainData, foot-phase labels
    layers.py          dense / MLP / LSTM / mixture-of-experts on plain param dicts, time-to-arrival embedding
    base_path.py       the residual decoder's base: Slerp / lerp, or Hermite from the start's velocity
    model.py           init_params, phase network, encoder / decoder step, bi-directional rollout, stitching, sample
    losses.py          state / KL / FK / stitching / phase losses, discriminators and LSGAN losses
    deferred_grads.py  training-only speed-up: the largest weight gradients as one matmul after the scan
    train.py           load_data, make_training (init / step / batch functions, run metadata)
    infer.py           load(run), sample_transitions on windows, infill(args, run) on users' keyframes
    context.py         inference inside a clip: the fill onto the Hermite path through the neighbouring frames
    bench.py           the model's rows of the Table 1 layout beside Slerp, error-over-time plot
"""

INFILL_OPTIONS = {   # ``inbetween infill --model scvae``: dest -> (metavar, help)
    "start": ("FILE.bvh[:FRAME]", "start keyframe (default frame 0)"),
    "end": ("FILE.bvh[:FRAME]", "end keyframe (default last frame)"),
    "frames": ("N", "generated frames between the keyframes"),
}
