"""``python -m inbetween_jax.cli ...`` == ``inbetween ...``."""
from inbetween_jax.cli import entry

entry()
