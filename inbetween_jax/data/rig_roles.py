"""A humanoid rig's joints read by their roles, for rigs outside :data:`~inbetween_jax.data.rig_transfer.RIGS`.

The bone-direction transfer (:mod:`inbetween_jax.data.rig_transfer`) needs a few joints under the MotionBuilder
names: hips, the bottom and top of the spine, neck, head, and per side upper arm, forearm, hand (a finger
optional), thigh, shin, foot and toe.  :func:`role_aliases` finds them from the joint names' words and the
hierarchy, whatever the naming (``thigh_l``, ``UpperLeg_L``, ``LeftHip``, ``lFoot``, a ``namespace:`` prefix):

* a side is a word ``l`` / ``left`` or ``r`` / ``right`` (``LeftUpLeg``, ``thigh_l``, ``lFoot``, ``LHipJoint``);
* a hand is the shallowest joint of a side with a word ``hand`` or ``wrist`` (and no finger word); its parent is
  the forearm, that one's parent the upper arm; a foot the shallowest with ``foot`` or ``ankle`` (no toe word),
  its parent the shin, that one's parent the thigh; the toe the foot's first child;
* the hips are where the two thighs' chains meet, the chest (the top of the spine) where the two upper arms' meet,
  the spine's bottom the chest's ancestor just below the hips; the head the shallowest joint below the chest with
  a word ``head`` (not ``top`` / ``end``), the neck its parent.

Anything inconsistent (a side missing, the chest not above both arms and below the hips, no joint between hips and
chest or between chest and head) gives None: the rig is refused as before.  Pure Python.
"""
from __future__ import annotations

import re

__all__ = ["role_aliases", "words"]

_FINGER = {"thumb", "index", "middle", "mid", "ring", "pinky", "little", "finger", "fingers"}
_TOE = {"toe", "toes", "ball", "toebase"}
_NOT_HEAD = {"top", "end", "nub", "site", "tip"}
_SIDES = {"l": "Left", "left": "Left", "r": "Right", "right": "Right"}


def words(name: str) -> list:
    """Lower-case words of a joint name: ``"LHipJoint"`` -> ``["l", "hip", "joint"]``, ``"thigh_l"`` ->
    ``["thigh", "l"]``, ``"mixamorig:LeftArm"`` -> ``["left", "arm"]``."""
    name = name.rsplit(":", 1)[-1]
    return [w.lower() for w in re.findall(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+|\d+", name)]


def _side(ws) -> str | None:
    found = {_SIDES[w] for w in ws if w in _SIDES}
    return found.pop() if len(found) == 1 else None


def _chain(parents, j) -> list:
    """``j`` and its ancestors up to the root."""
    out = [j]
    while parents[out[-1]] >= 0:
        out.append(parents[out[-1]])
    return out


def _meet(parents, a: int, b: int) -> int:
    """The deepest joint above (or at) both ``a`` and ``b``."""
    above = set(_chain(parents, a))
    return next(j for j in _chain(parents, b) if j in above)


def role_aliases(skeleton) -> dict | None:
    """{joint name: MotionBuilder name} for every joint of ``skeleton`` (the joints without a role get a name that
    cannot collide: ``"<name> (unused)"``), or None when the roles cannot all be found consistently."""
    names, parents = list(skeleton.names), list(skeleton.parents)
    ws = [words(n) for n in names]
    depth = [len(_chain(parents, j)) for j in range(len(names))]

    def shallowest(side, want, avoid):
        hits = [j for j in range(len(names)) if _side(ws[j]) == side and want & set(ws[j]) and not avoid & set(ws[j])]
        return min(hits, key=lambda j: depth[j]) if hits else None

    role = {}
    for side in ("Left", "Right"):
        hand = shallowest(side, {"hand", "wrist"}, _FINGER)
        foot = shallowest(side, {"foot", "ankle"}, _TOE)
        if hand is None or foot is None or min(depth[hand], depth[foot]) < 4 or not skeleton.children(foot):
            return None
        fingers = [k for k in range(len(names)) if hand in _chain(parents, k)[1:] and {"index", "middle", "mid"}
                   & set(ws[k])]
        role.update({f"{side}Hand": hand, f"{side}ForeArm": parents[hand], f"{side}Arm": parents[parents[hand]],
                     f"{side}Foot": foot, f"{side}Leg": parents[foot], f"{side}UpLeg": parents[parents[foot]],
                     f"{side}ToeBase": skeleton.children(foot)[0]})
        if fingers:
            role[f"{side}HandIndex1"] = min(fingers, key=lambda k: depth[k])
    hips = _meet(parents, role["LeftUpLeg"], role["RightUpLeg"])
    chest = _meet(parents, role["LeftArm"], role["RightArm"])
    up = _chain(parents, chest)
    if hips not in up[1:] or up.index(hips) < 2:          # the chest below the hips, a joint between them
        return None
    heads = [j for j in range(len(names)) if "head" in ws[j] and not _NOT_HEAD & set(ws[j])
             and chest in _chain(parents, j)[2:]]
    if not heads:
        return None
    head = min(heads, key=lambda j: depth[j])
    role.update({"Hips": hips, "Spine1": chest, "Spine": up[up.index(hips) - 1], "Head": head,
                 "Neck1": parents[head]})
    if len(set(role.values())) != len(role):
        return None
    alias = {names[j]: f"{names[j]} (unused)" for j in range(len(names))}
    alias.update({names[j]: canonical for canonical, j in role.items()})
    return {n.rsplit(":", 1)[-1]: c for n, c in alias.items()}
