"""Two-character interaction in-betweening (Zhang et al. 2025, "Motion In-Betweening for Densely Interacting
Characters"): cross-space in-betweening (DCT + conv1d/GCN encoder, relative-space VAE + FiLM, decoder), a
motion refiner and a periodic-autoencoder interaction critic on pairwise-joint-distance dynamics.

Files: ``config.py`` presets; ``features.py`` the representation (per-character world features, rigid
keypose / root spaces, ``apply_space``); ``data.py`` paired clips (real or constructed), splits, training
batches and evaluation windows; ``layers.py`` the flax ``nnx`` blocks; ``model.py`` parameters (plain dicts)
and the pure generator step / refiner / rollouts; ``losses.py`` the loss terms; ``train.py`` the training
step for :func:`inbetween_jax.train.run_training`; ``infer.py`` restoring a run and infilling users' BVH
files; ``bench.py`` the paper's Table 1 rows (protocol in :mod:`inbetween_jax.evaluation.interaction`).
"""

INFILL_OPTIONS = {   # ``inbetween infill --model interaction``: dest -> (metavar, help)
    "a": ("FILE.bvh[:START]", "character A's context up to its start frame (default last frame)"),
    "b": ("FILE.bvh[:START]", "character B's context up to its start frame (default last frame)"),
    "key_a": ("FILE.bvh[:FRAME]", "A's keyframe (default last frame)"),
    "key_b": ("FILE.bvh[:FRAME]", "B's keyframe (default last frame)"),
    "frames": ("N", "generated frames between the start frames and the keyframes (models trained with "
                    "model.tta, the default preset, arrive at the keyframes after N frames)"),
}
