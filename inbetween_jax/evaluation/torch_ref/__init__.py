"""PyTorch references of the training steps, for the speed section of ``make bench`` (``inbetween speed``).

:mod:`.scvae` (the S-CVAE step) and :mod:`.cae` (the CAE step) mirror the JAX steps with the same matrix and
convolution sizes; parity tests check the same losses from the same weights.  ``torch`` is optional (the
``bench`` extra); both modules import without it and ``available()`` says whether they can run.
"""
