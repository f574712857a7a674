"""The model registry: name -> :class:`~inbetween_jax.models.spec.ModelSpec`.

Train, bench, the CLI, the demo and sweeps iterate over :data:`REGISTRY`; adding a model is one package
``inbetween_jax/models/<name>/`` with the file roles of :mod:`inbetween_jax.models.spec` plus one line here.
"""
from inbetween_jax.models.spec import ModelSpec, Training

REGISTRY = {spec.name: spec for spec in (
    ModelSpec("scvae", "inbetween_jax.models.scvae",
              "S-CVAE: bi-directional stitching CVAE between two keyframes"),
    ModelSpec("cae", "inbetween_jax.models.cae",
              "convolutional inpainting autoencoder: fills gaps of a motion"),
    ModelSpec("interaction", "inbetween_jax.models.interaction",
              "two-character interaction in-betweening (DCT + GCN + FiLM VAE, refiner, PAE critic)"),
)}
MODELS = tuple(REGISTRY)


def get_spec(name: str) -> ModelSpec:
    """The registered model ``name``; ValueError (one line, listing the choices) for an unknown name."""
    try:
        return REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown model {name!r} (choose {', '.join(MODELS)})") from None


__all__ = ["REGISTRY", "MODELS", "ModelSpec", "Training", "get_spec"]
