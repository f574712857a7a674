"""Captures on another rig put on the 43-joint body of ``cmu_bvh`` / ``cmu_more/daz43`` by bone directions: CMU's
31-joint "MotionBuilder-friendly" rig (``cmu_more/mb31``), so those captures can train models of that body, and, for
``inbetween infill``, users' files on the common three-spine-joint rigs (LaFAN1's ``Hips``, ``Spine``, ``Spine1``,
``Spine2``, ``Neck``, ``LeftToe``, ...; Mixamo-style names with a ``namespace:`` prefix and ``ToeBase`` toes).

Each output frame puts the template body's bones along the directions of the matching bones of the capture
(swing only: no twist about a bone's own axis); the hips and chest are oriented by their up and left-right
vectors; collars, buttocks, head, eyes and fingers keep their rest rotation.  The root is placed so that the hip
sockets follow the capture's, scaled by the ratio of the two bodies' leg lengths, so the capture's length unit
does not matter (the mb31 unit is 0.056444 m, :data:`MB_UNIT_CM`).  A hand without a finger joint in the capture
(LaFAN1) keeps its rest rotation.  A leading T-pose frame (cgspeed's frame 0) is dropped.  Pure NumPy.

The same 31-joint hierarchy also comes with CMU's ASF bone names (``hip``, ``lfemur``, ...: ``cmu_bvh/16_01.bvh``,
``16_02``, ``18_01_subjectA_414Group``, in the same unit); :data:`ASF31_TO_MB31` maps them, so those files take the
same route.  Each known rig is a name map onto the MotionBuilder names (:data:`RIGS`); :func:`rig_profile`
finds a file's.  Any other humanoid rig is read by its joints' roles (:mod:`inbetween_jax.data.rig_roles`:
``pelvis``, ``thigh_l``, ``UpperArm_L``, ...), :func:`rig_of`.  :func:`transfer_back` puts a motion generated on
the body back on the user's rig by the same bones, with the user's own frames kept exactly where they are known.
"""
from __future__ import annotations

import numpy as np

from inbetween_jax.errors import UserError

__all__ = ["MB_UNIT_CM", "MB31_JOINTS", "OPTIONAL_JOINTS", "ASF31_TO_MB31", "SPINE3_TO_MB31", "RIGS", "SWING",
           "FRAMED", "rig_profile", "rig_of", "rig_label", "canonical_names", "on_31_joint_rig", "takes_rig_transfer",
           "transfer_rig", "transfer_back"]

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
OPTIONAL_JOINTS = ("LeftHandIndex1", "RightHandIndex1")     # without them the hands keep their rest rotation
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
# rigs whose spine is Spine -> Spine1 -> Spine2 (shoulders on Spine2) and neck Neck -> Head (LaFAN1, Mixamo):
# their top spine joint plays the MotionBuilder Spine1 (the chest), their Neck its Neck1; the middle joint is unused
SPINE3_TO_MB31 = {"Spine1": "Spine1 (middle)", "Spine2": "Spine1", "Neck": "Neck1", "LeftToe": "LeftToeBase",
                  "RightToe": "RightToeBase"}
# profile -> (what a note calls it, capture name -> MotionBuilder name (names not in the map are taken as they
# are), cm per capture unit: only ratios of lengths are used, so it changes nothing but the last bits, which the
# training captures keep as they were built)
RIGS = {
    "mb31": ("31-joint CMU rig", {}, MB_UNIT_CM),
    "cmu-asf": ("31-joint CMU rig", ASF31_TO_MB31, MB_UNIT_CM),
    "spine3": ("three-spine-joint rig (LaFAN1 / Mixamo names)", SPINE3_TO_MB31, 1.0),
}


ROLES_LABEL = "rig, read by its joints' roles (sides, hands, feet, spine, head),"


def canonical_names(names, profile: str, alias: dict | None = None) -> list:
    """A capture's joint ``names`` under the MotionBuilder names of :data:`RIGS` ``[profile]`` (or of ``alias``,
    :func:`rig_of`'s), a ``namespace:`` prefix dropped."""
    alias = RIGS[profile][1] if alias is None else alias
    return [alias.get(n.rsplit(":", 1)[-1], n.rsplit(":", 1)[-1]) for n in names]


def rig_profile(names) -> str | None:
    """The first profile of :data:`RIGS` under which joint ``names`` hold every joint :func:`transfer_rig` reads
    (:data:`OPTIONAL_JOINTS` may be missing), else None."""
    need = set(MB31_JOINTS) - set(OPTIONAL_JOINTS)
    return next((p for p in RIGS if need <= set(canonical_names(names, p))), None)


def rig_of(skeleton) -> tuple | None:
    """``(profile, alias)`` of a capture's skeleton: a rig of :data:`RIGS` by its names, else (``"roles"``) its
    joints read by their roles from the names' words and the hierarchy
    (:func:`~inbetween_jax.data.rig_roles.role_aliases`); None when neither finds every joint the transfer needs."""
    profile = rig_profile(skeleton.names)
    if profile is not None:
        return profile, RIGS[profile][1]
    from inbetween_jax.data.rig_roles import role_aliases
    alias = role_aliases(skeleton)
    return None if alias is None else ("roles", alias)


def rig_label(profile: str) -> str:
    """What a note calls a rig of :func:`rig_of`."""
    return RIGS[profile][0] if profile in RIGS else ROLES_LABEL


def on_31_joint_rig(names) -> bool:
    """Whether joint ``names`` are CMU's 31-joint rig (under either naming): the captures the ``cmu`` source
    trains on."""
    return rig_profile(names) in ("mb31", "cmu-asf")


def takes_rig_transfer(skeleton) -> bool:
    """Whether :func:`transfer_rig` can put a capture on ``skeleton`` (every joint it sets, and a child or an end
    site for each swung bone)."""
    names = set(skeleton.names)
    ends = {p for p, _ in skeleton.end_sites}
    need = set(SWING) | set(FRAMED) | {n for (up, _), (side, _) in FRAMED.values() for n in (up,) + side}
    if not need <= names:
        return False
    idx = {n: i for i, n in enumerate(skeleton.names)}
    return all(c in names or idx[j] in ends for j, (c, _) in SWING.items())


def _unit(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def _leg_length(skel) -> float:
    """Shin plus foot bone of the 43-joint body (or a checkpoint's subset of it): the length that scales the root."""
    idx = {n: i for i, n in enumerate(skel.names)}
    return float(np.linalg.norm(skel.offsets[idx["lShin"]]) + np.linalg.norm(skel.offsets[idx["lFoot"]]))


def _frame(up, side):
    """(..., 3, 3) rotation matrices whose columns are up, side made orthogonal to it, and their cross."""
    e1 = _unit(up)
    e2 = _unit(side - np.sum(side * e1, -1, keepdims=True) * e1)
    return np.stack([e1, e2, np.cross(e1, e2)], -1)


def transfer_rig(capture, template, drop_tpose: bool = True):
    """capture: a :class:`~inbetween_jax.data.bvh.Motion` on a rig of :data:`RIGS` (the 31-joint ``Hips``,
    ``LeftUpLeg``, ..., its ASF names ``hip``, ``lfemur``, ..., or LaFAN1's ``Hips``, ``Spine2``, ...) or one
    :func:`rig_of` reads by roles; template: one on the 43-joint body (``hip``, ``abdomen``, ...), or its
    :class:`~inbetween_jax.data.bvh.Skeleton`, or a subset of it holding every joint :data:`SWING` and
    :data:`FRAMED` set (a checkpoint's 21-joint body: bones without their child take the end site's direction).
    Returns the capture's frames, but a leading T-pose frame (kept with ``drop_tpose=False``, so frame numbers
    stay the file's), as a Motion on the template's skeleton, positions in the template's unit.

    Raises UserError (one line, naming the file) when the capture is on none of them (the joints it lacks under
    the 31-joint names)."""
    from inbetween_jax.data.bvh import Motion
    found = rig_of(capture.skeleton)
    if found is None:
        cnames = canonical_names(capture.skeleton.names, "mb31")
        missing = [n for n in MB31_JOINTS if n not in cnames and n not in OPTIONAL_JOINTS]
        raise UserError(f"{capture.source}: not a rig known to the bone-direction transfer (CMU's 31-joint, LaFAN1 "
                        f"or Mixamo names, nor hands, feet, spine and head found by joint roles; no "
                        f"{', '.join(missing[:4])})")
    profile, alias = found
    cnames = canonical_names(capture.skeleton.names, profile, alias)
    from inbetween_jax.geometry.kinematics import forward_kinematics, inverse_kinematics
    from inbetween_jax.geometry.quaternion import (quat_between, quat_fix_sign_np, quat_from_matrix, quat_mul,
                                                   quat_rotate)
    skel = getattr(template, "skeleton", template)
    names, parents = list(skel.names), skel.parents
    idx = {n: i for i, n in enumerate(names)}
    q0 = np.asarray(capture.local_quats[0, 1:, 0], np.float64)
    first = 1 if drop_tpose and capture.num_frames > 1 and float(np.abs(1.0 - np.abs(q0)).max()) < TPOSE_TOL else 0
    cap = capture.global_positions()[first:] * (RIGS[profile][2] if profile in RIGS else 1.0)   # cm on CMU rigs
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
        elif name in SWING and all(n in cidx for n in SWING[name][1]):
            child, pair = SWING[name]
            bone = skel.offsets[idx[child]] if child in idx else ends[j]
            now = quat_rotate(pq, np.broadcast_to(np.asarray(bone, np.float64), (t_len, 3)))
            glob[:, j] = quat_mul(quat_between(_unit(now), _unit(cvec(pair))), pq)
        else:
            glob[:, j] = pq                                                  # rest rotation
    local = inverse_kinematics(glob, np.zeros(glob.shape[:-1] + (3,)), parents)[0]     # rotations only
    local = quat_fix_sign_np(local / np.linalg.norm(local, axis=-1, keepdims=True), axis=0)
    leg_t = _leg_length(skel)
    leg_c = np.median(np.linalg.norm(cvec(("LeftUpLeg", "LeftLeg")), axis=-1)
                      + np.linalg.norm(cvec(("LeftLeg", "LeftFoot")), axis=-1))
    pos = np.broadcast_to(skel.offsets.astype(np.float64), (t_len, j_len, 3)).copy()
    thighs_t = 0.5 * (rest[idx["rThigh"]] + rest[idx["lThigh"]])             # hip sockets, rest, from the root
    thighs_c = 0.5 * (cap[:, cidx["RightUpLeg"]] + cap[:, cidx["LeftUpLeg"]])
    pos[:, 0] = thighs_c * (leg_t / leg_c) - quat_rotate(glob[:, 0], np.broadcast_to(thighs_t, (t_len, 3)))
    return Motion(skel, local, pos, capture.frame_time, source=capture.source)


# the same correspondences read the other way: a capture-rig joint (MotionBuilder name) -> the far end of its bone
# and the body bone it follows (joint, child; child None: the joint's end site) ...
INVERSE_SWING = {a: (b, (tj, tc)) for tj, (tc, (a, b)) in SWING.items()}
# ... and the two framed joints: (up: far end, body pair), (side: capture pair, body pair)
INVERSE_FRAMED = {ua: ((ub, (tj, tu)), (side_c, side_t)) for tj, ((tu, (ua, ub)), (side_t, side_c)) in FRAMED.items()}


def _down(parents, offsets, q, a: int, b: int):
    """(T, 3): joint ``b`` (below joint ``a``) relative to ``a``, in ``a``'s frame, the joints between them at
    their local rotations ``q`` (T, J, 4); ``offsets`` (T, J, 3) the local positions."""
    from inbetween_jax.geometry.quaternion import quat_rotate
    path = [b]
    while path[-1] != a:
        if path[-1] < 0:
            raise ValueError(f"joint {b} is not below joint {a}")
        path.append(parents[path[-1]])
    v = offsets[:, b]
    for j in path[1:-1]:
        v = offsets[:, j] + quat_rotate(q[:, j], v)
    return v


def transfer_back(generated, user, known=None):
    """A motion generated on the body (the checkpoint's joints, as :func:`transfer_rig` put the user's file there)
    back on the user's rig (``user``: a Motion on a rig :func:`rig_of` reads, the same frame count, whose ``known``
    frames hold the user's values; default: the first and the last frame).

    Each capture-rig bone of :data:`SWING` / :data:`FRAMED` is turned to point along the body bone it was read
    from, the root placed so the hip sockets follow the body's (scaled by the ratio of the leg lengths); the other
    joints keep the user's rotations, slerped between known frames.  What the transfer cannot carry (twist about a
    bone, the joints it does not read) is restored from the known frames: the difference between the user's frame
    and its round trip, a rotation in each joint's own frame (about the bone for a turned bone, so the bone keeps
    its direction), is slerped (root: lerped) across each run of generated frames; the known frames come back
    exactly and the generated ones join them without a jump.  Joints are visited parents first, each turned from
    its parent's final rotation.  Returns a Motion with ``user``'s skeleton and ``generated``'s frame time."""
    import dataclasses
    from inbetween_jax.data.resample import fill_unknown, known_frames
    from inbetween_jax.geometry.kinematics import forward_kinematics
    from inbetween_jax.geometry.quaternion import (quat_between, quat_fix_sign_np, quat_from_matrix, quat_inv,
                                                   quat_mul, quat_rotate)
    t_len, usk, bsk = generated.num_frames, user.skeleton, generated.skeleton
    known = known_frames(generated, user, known, "transfer_back")
    found = rig_of(usk)
    if found is None:
        raise UserError(f"{user.source}: not a rig known to the bone-direction transfer")
    cnames = canonical_names(usk.names, *found)
    cidx = {n: i for i, n in enumerate(cnames)}
    bidx = {n: i for i, n in enumerate(bsk.names)}
    ends = {p: np.asarray(o, np.float64) for p, o in bsk.end_sites}
    gq, gp = (np.asarray(x, np.float64) for x in forward_kinematics(
        np.asarray(generated.local_quats, np.float64), np.asarray(generated.local_pos, np.float64), bsk.parents))
    uq = fill_unknown(user.local_quats, known, rotations=True)          # (T, Ju, 4) the user's, across the gaps
    up = fill_unknown(user.local_pos, known, rotations=False)

    def body(a, b):                     # (T, 3) body bone a -> b (b None: a's end site)
        if b is None or b not in bidx:
            return quat_rotate(gq[:, bidx[a]], np.broadcast_to(ends[bidx[a]], (t_len, 3)))
        return gp[:, bidx[b]] - gp[:, bidx[a]]

    def have(*names):
        return all(n in cidx for n in names)

    user_q = np.asarray(user.local_quats, np.float64)
    q, glob = uq.copy(), np.empty_like(uq)
    for j, parent in enumerate(usk.parents):
        pq = glob[:, parent] if parent >= 0 else np.tile([1.0, 0, 0, 0], (t_len, 1))
        c = cnames[j]
        framed, swung = INVERSE_FRAMED.get(c), INVERSE_SWING.get(c)
        if framed and have(framed[0][0], *framed[1][0]):
            (ub, up_pair), (side_c, side_t) = framed
            mine = _down(usk.parents, up, q, j, cidx[ub]), (_down(usk.parents, up, q, j, cidx[side_c[1]])
                                                           - _down(usk.parents, up, q, j, cidx[side_c[0]]))
            target = _frame(body(*up_pair), body(*side_t))
            g = quat_from_matrix(target @ np.swapaxes(_frame(*mine), -1, -2))
        elif swung and have(swung[0]) and swung[1][0] in bidx and (swung[1][1] in bidx or bidx[swung[1][0]] in ends):
            now = quat_rotate(pq, _down(usk.parents, up, q, j, cidx[swung[0]]))
            g = quat_mul(quat_between(_unit(now), _unit(body(*swung[1]))), pq)
        else:
            g = quat_mul(pq, q[:, j])
        local = quat_mul(quat_inv(pq), g)
        # what the round trip lost at the known frames (for a turned bone a twist about it), spread across the gaps
        delta = quat_mul(quat_inv(local), user_q[:, j])
        delta = fill_unknown(np.where(delta[..., :1] < 0, -delta, delta)[:, None], known, rotations=True)[:, 0]
        q[:, j] = quat_mul(local, delta)
        q[known, j] = user_q[known, j]
        glob[:, j] = quat_mul(pq, q[:, j])
    ident = [1.0, 0, 0, 0]

    def chain(a, b):                    # the user's rest bone a -> b, per frame (the joints between at rest)
        return _down(usk.parents, up, np.broadcast_to(ident, q.shape), cidx[a], cidx[b])

    leg_u = np.median(np.linalg.norm(chain("LeftUpLeg", "LeftLeg"), axis=-1)
                      + np.linalg.norm(chain("LeftLeg", "LeftFoot"), axis=-1))
    leg_b = _leg_length(bsk)
    sockets_b = 0.5 * (gp[:, bidx["rThigh"]] + gp[:, bidx["lThigh"]])
    sockets_u = 0.5 * sum(_down(usk.parents, up, q, 0, cidx[n]) for n in ("RightUpLeg", "LeftUpLeg"))
    root = sockets_b * (leg_u / leg_b) - quat_rotate(glob[:, 0], sockets_u)
    shift = fill_unknown((np.asarray(user.local_pos, np.float64)[:, 0] - root)[:, None], known, rotations=False)
    out_q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    out_q[known] = user_q[known]
    out_q[~known] = quat_fix_sign_np(out_q, axis=0)[~known]
    out_p = up.copy()
    out_p[:, 0] = root + shift[:, 0]
    out_p[known] = np.asarray(user.local_pos, np.float64)[known]
    return dataclasses.replace(user, local_quats=out_q, local_pos=out_p, frame_time=generated.frame_time)
