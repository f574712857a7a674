"""Non-learned in-betweening baselines."""
from inbetween_jax.baselines.interpolation import interpolate_transition  # noqa: F401
from inbetween_jax.baselines.linear_fill import linear_fill  # noqa: F401
from inbetween_jax.baselines.hermite_fill import hermite_fill  # noqa: F401
from inbetween_jax.baselines.zero_velocity import zero_velocity_transition  # noqa: F401
from inbetween_jax.baselines.two_character import two_character_interpolation  # noqa: F401
from inbetween_jax.baselines.velocity_interpolation import velocity_interpolate_transition  # noqa: F401
