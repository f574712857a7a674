"""Pure jnp geometry: quaternions, forward / inverse kinematics, DCT."""
from inbetween_jax.geometry.quaternion import (  # noqa: F401
    quat_align, quat_between, quat_conj, quat_fix_sign, quat_fix_sign_np, quat_from_axis_angle, quat_from_euler,
    quat_from_forward_up, quat_from_matrix, quat_identity, quat_inv, quat_mul, quat_normalize,
    quat_rotate, quat_slerp, quat_to_axis_angle, quat_to_euler, quat_to_forward_up, quat_to_matrix)
from inbetween_jax.geometry.heading import heading_angle, rotate_about_up, yaw_matrix, yaw_quat  # noqa: F401
from inbetween_jax.geometry.kinematics import (  # noqa: F401
    bone_lengths, forward_kinematics, inverse_kinematics, local_positions)
from inbetween_jax.geometry.dct import dct, dct_matrix, idct  # noqa: F401
from inbetween_jax.geometry.fit import fit_rotations  # noqa: F401
from inbetween_jax.geometry.mirror import mirror_pose, rest_side_axis  # noqa: F401
