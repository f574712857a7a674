"""CMU captures on the 31-joint "MotionBuilder-friendly" rig (``cmu_more/mb31``) put on the 43-joint body of
``cmu_bvh`` / ``cmu_more/daz43`` by bone directions, so they can train models of that body.

Each output frame puts the template body's bones along the directions of the matching bones of the capture
(swing only: no twist about a bone's own axis); the hips and chest are oriented by their up and left-right
vectors; collars, buttocks, head, eyes and fingers keep their rest rotation.  The root is placed so that the hip
sockets follow the capture's, scaled by the ratio of the two bodies' leg lengths (the mb31 unit is 0.056444 m,
:data:`MB_UNIT_CM`).  A leading T-pose frame (cgspeed's frame 0) is dropped.  Pure NumPy.

The same 31-joint hierarchy also comes with CMU's ASF bone names (``hip``, ``lfemur``, ...: ``cmu_bvh/16_01.bvh``,
``16_02``, ``18_01_subjectA_414Group``, in the same unit); :data:`ASF31_TO_MB31` maps them, so those files take the
same route.
"""
from __future__ import annotations

import numpy as np

from inbetween_jax.errors import UserError

__all__ = ["MB_UNIT_CM", "MB31_JOINTS", "ASF31_TO_MB31", "SWING", "FRAMED", "on_31_joint_rig", "takes_31_joint_rig",
           "transfer_mb31"]

MB_UNIT_CM = 5.6444
TPOSE_TOL = 0.03            # max |1 - |w|| of the non-root rotations for frame 0 to count as the rest T-pose
# template joint -> (its child giving the bone, capture joint pair (from, to)) for the swing-aligned bones
SWING = {
    "abdomen": ("chest", ("Spine", "Spine1")),
    "neck": ("head", ("Neck1", "Head")),
    "rShldr": ("rForeArm", ("RightArm", "RightForeArm")),
    "rForeArm": ("rHand", ("RightForeArm", "RightHand")),
    "rHand": ("rMid1", ("RightHand", "RightHandIndex1")),
    "lShldr": ("lForeArm", ("LeftArm", "LeftForeArm")),
    "lForeArm": ("lHand", ("LeftForeArm", "LeftHand")),
    "lHand": ("lMid1", ("LeftHand", "LeftHandIndex1")),
    "rThigh": ("rShin", ("RightUpLeg", "RightLeg")),
    "rShin": ("rFoot", ("RightLeg", "RightFoot")),
    "rFoot": (None, ("RightFoot", "RightToeBase")),
    "lThigh": ("lShin", ("LeftUpLeg", "LeftLeg")),
    "lShin": ("lFoot", ("LeftLeg", "LeftFoot")),
    "lFoot": (None, ("LeftFoot", "LeftToeBase")),
}
# template joint -> (up: child, capture pair), (side: template pair, capture pair) for the two framed joints
FRAMED = {
    "hip": (("abdomen", ("Hips", "Spine")), (("rThigh", "lThigh"), ("RightUpLeg", "LeftUpLeg"))),
    "chest": (("neck", ("Spine1", "Neck1")), (("rShldr", "lShldr"), ("RightArm", "LeftArm"))),
}
MB31_JOINTS = tuple(sorted({n for _, pair in SWING.values() for n in pair}
                           | {n for (_, up), (_, side) in FRAMED.values() for n in up + side}))
# CMU's ASF bone names of the same hierarchy -> the MotionBuilder names above
ASF31_TO_MB31 = {
    "hip": "Hips", "lowerback": "LowerBack", "upperback": "Spine", "thorax": "Spine1", "lowerneck": "Neck",
    "upperneck": "Neck1", "head": "Head",
    **{f"{s}{a}": f"{side}{m}" for s, side in (("l", "Left"), ("r", "Right")) for a, m in (
        ("femur", "UpLeg"), ("tibia", "Leg"), ("foot", "Foot"), ("toes", "ToeBase"), ("clavicle", "Shoulder"),
        ("humerus", "Arm"), ("radius", "ForeArm"), ("wrist", "Hand"), ("hand", "FingerBase"),
        ("fingers", "HandIndex1"))},
    "lhipjoint": "LHipJoint", "rhipjoint": "RHipJoint", "lthumb": "LThumb", "rthumb": "RThumb",
}


def on_31_joint_rig(names) -> bool:
    """Whether joint ``names`` hold every joint :func:`transfer_mb31` reads, under either naming."""
    names = {ASF31_TO_MB31.get(n, n) for n in names}
    return set(MB31_JOINTS) <= names


def takes_31_joint_rig(skeleton) -> bool:
    """Whether :func:`transfer_mb31` can put a 31-joint capture on ``skeleton`` (every joint it sets, and a child
    or an end site for each swung bone)."""
    names = set(skeleton.names)
    ends = {p for p, _ in skeleton.end_sites}
    need = set(SWING) | set(FRAMED) | {n for (up, _), (side, _) in FRAMED.values() for n in (up,) + side}
    if not need <= names:
        return False
    idx = {n: i for i, n in enumerate(skeleton.names)}
    return all(c in names or idx[j] in ends for j, (c, _) in SWING.items())


def _unit(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def _frame(up, side):
    """(..., 3, 3) rotation matrices whose columns are up, side made orthogonal to it, and their cross."""
    e1 = _unit(up)
    e2 = _unit(side - np.sum(side * e1, -1, keepdims=True) * e1)
    return np.stack([e1, e2, np.cross(e1, e2)], -1)


def transfer_mb31(capture, template, drop_tpose: bool = True):
    """capture: a :class:`~inbetween_jax.data.bvh.Motion` on the 31-joint rig (``Hips``, ``LeftUpLeg``, ... or
    the ASF names ``hip``, ``lfemur``, ...); template: one on the 43-joint body (``hip``, ``abdomen``, ...), or its
    :class:`~inbetween_jax.data.bvh.Skeleton`, or a subset of it holding every joint :data:`SWING` and
    :data:`FRAMED` set (a checkpoint's 21-joint body: bones without their child take the end site's direction).
    Returns the capture's frames, but a leading T-pose frame (kept with ``drop_tpose=False``, so frame numbers
    stay the file's), as a Motion on the template's skeleton, positions in the template's unit.

    Raises UserError (one line, naming the file) when the capture lacks a joint of :data:`MB31_JOINTS`."""
    from inbetween_jax.data.bvh import Motion
    cnames = [ASF31_TO_MB31.get(n, n) for n in capture.skeleton.names]
    missing = [n for n in MB31_JOINTS if n not in cnames]
    if missing:
        raise UserError(f"{capture.source}: not the 31-joint CMU rig (no {', '.join(missing[:4])})")
    from inbetween_jax.geometry.kinematics import forward_kinematics, inverse_kinematics
    from inbetween_jax.geometry.quaternion import (quat_between, quat_fix_sign_np, quat_from_matrix, quat_mul,
                                                   quat_rotate)
    skel = getattr(template, "skeleton", template)
    names, parents = list(skel.names), skel.parents
    idx = {n: i for i, n in enumerate(names)}
    q0 = np.asarray(capture.local_quats[0, 1:, 0], np.float64)
    first = 1 if drop_tpose and capture.num_frames > 1 and float(np.abs(1.0 - np.abs(q0)).max()) < TPOSE_TOL else 0
    cap = capture.global_positions()[first:] * MB_UNIT_CM                 # (T, Jc, 3) cm
    cidx = {n: i for i, n in enumerate(cnames)}
    t_len, j_len = cap.shape[0], len(names)
    rest = forward_kinematics(np.tile([1.0, 0, 0, 0], (1, j_len, 1)), skel.offsets[None].astype(np.float64),
                              parents)[1][0]                              # (J, 3) rest positions
    ends = {p: o for p, o in skel.end_sites}

    def cvec(pair):
        return cap[:, cidx[pair[1]]] - cap[:, cidx[pair[0]]]

    def rvec(a, b):
        return np.broadcast_to(rest[idx[b]] - rest[idx[a]], (t_len, 3))

    glob = np.tile(np.array([1.0, 0, 0, 0]), (t_len, j_len, 1))
    for j, name in enumerate(names):                                        # parents come first in BVH order
        pq = glob[:, parents[j]] if parents[j] >= 0 else np.tile([1.0, 0, 0, 0], (t_len, 1))
        if name in FRAMED:
            (up_child, up_pair), (side_t, side_c) = FRAMED[name]
            fr = _frame(rvec(name, up_child), rvec(*side_t))
            ft = _frame(cvec(up_pair), cvec(side_c))
            glob[:, j] = quat_from_matrix(ft @ np.swapaxes(fr, -1, -2))
        elif name in SWING:
            child, pair = SWING[name]
            bone = skel.offsets[idx[child]] if child in idx else ends[j]
            now = quat_rotate(pq, np.broadcast_to(np.asarray(bone, np.float64), (t_len, 3)))
            glob[:, j] = quat_mul(quat_between(_unit(now), _unit(cvec(pair))), pq)
        else:
            glob[:, j] = pq                                                  # rest rotation
    local = inverse_kinematics(glob, np.zeros(glob.shape[:-1] + (3,)), parents)[0]     # rotations only
    local = quat_fix_sign_np(local / np.linalg.norm(local, axis=-1, keepdims=True), axis=0)
    leg_t = np.linalg.norm(skel.offsets[idx["lShin"]]) + np.linalg.norm(skel.offsets[idx["lFoot"]])
    leg_c = np.median(np.linalg.norm(cvec(("LeftUpLeg", "LeftLeg")), axis=-1)
                      + np.linalg.norm(cvec(("LeftLeg", "LeftFoot")), axis=-1))
    pos = np.broadcast_to(skel.offsets.astype(np.float64), (t_len, j_len, 3)).copy()
    thighs_t = 0.5 * (rest[idx["rThigh"]] + rest[idx["lThigh"]])             # hip sockets, rest, from the root
    thighs_c = 0.5 * (cap[:, cidx["RightUpLeg"]] + cap[:, cidx["LeftUpLeg"]])
    pos[:, 0] = thighs_c * (leg_t / leg_c) - quat_rotate(glob[:, 0], np.broadcast_to(thighs_t, (t_len, 3)))
    return Motion(skel, local, pos, capture.frame_time, source=capture.source)
