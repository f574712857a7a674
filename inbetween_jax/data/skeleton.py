"""Skeleton description shared by every dataset and model: names, parents, offsets, BVH channels."""
from __future__ import annotations

import dataclasses
import re
from typing import Optional, Sequence

import numpy as np

POSITION_CHANNELS = ("Xposition", "Yposition", "Zposition")
ROTATION_CHANNELS = ("Xrotation", "Yrotation", "Zrotation")


@dataclasses.dataclass(frozen=True, eq=False)
class Skeleton:
    """A joint hierarchy.

    names:    J joint names (root first).
    parents:  J parent indices, ``parents[0] == -1`` and ``parents[j] < j``.
    offsets:  (J, 3) float64 bone offsets in the parent's frame (row 0: the root's rest offset).
    channels: per joint, the BVH channel names in file order (e.g. ``("Zrotation", "Yrotation",
              "Xrotation")``); a joint with position channels has them as well.
    end_sites: ``(parent_index, offset (3,))`` of every ``End Site`` block, kept for writing BVH.
    """

    names: tuple
    parents: tuple
    offsets: np.ndarray
    channels: tuple
    end_sites: tuple = ()

    def __post_init__(self):
        j = len(self.names)
        if len(self.parents) != j or np.shape(self.offsets) != (j, 3) or len(self.channels) != j:
            raise ValueError(f"skeleton arrays disagree: {j} names, {len(self.parents)} parents, "
                             f"offsets {np.shape(self.offsets)}, {len(self.channels)} channel lists")
        if j == 0 or self.parents[0] != -1 or any(not 0 <= p < i for i, p in enumerate(self.parents) if i):
            raise ValueError("parents must start with -1 and every parent must come before its child")
        if len(set(self.names)) != j:
            raise ValueError("joint names must be unique")

    @property
    def num_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Index of joint ``name`` (KeyError with the known names otherwise)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no joint named {name!r}; joints are {list(self.names)}") from None

    def rotation_order(self, joint: int) -> str:
        """Euler order of ``joint`` as lower-case axes in file order, e.g. ``"zyx"``."""
        return "".join(c[0].lower() for c in self.channels[joint] if c in ROTATION_CHANNELS)

    def has_positions(self, joint: int) -> bool:
        return any(c in POSITION_CHANNELS for c in self.channels[joint])

    @property
    def num_channels(self) -> int:
        return sum(len(c) for c in self.channels)

    def children(self, joint: int) -> list:
        return [i for i, p in enumerate(self.parents) if p == joint]

    def same_topology(self, other: "Skeleton") -> bool:
        return self.names == other.names and self.parents == other.parents

    def foot_joints(self) -> tuple:
        """Indices ``(left_ankle, left_toe, right_ankle, right_toe)`` found by name.

        Handles LaFAN1 (LeftFoot/LeftToe), CMU-ASF (lfoot/ltoes) and CMU-Poser (lFoot, no toe) names.
        Where a skeleton has no toe joint the ankle is used twice.
        """
        def find(side: str, words: Sequence[str]) -> Optional[int]:
            pat = re.compile(rf"^(?:{side})[_ ]?(?:{'|'.join(words)})$", re.IGNORECASE)
            for i, n in enumerate(self.names):
                if pat.match(n):
                    return i
            return None

        out = []
        for side in ("left|l", "right|r"):
            ankle = find(side, ["foot", "ankle"])
            toe = find(side, ["toe", "toes", "toebase", "toe_base", "ball"])
            if ankle is None:
                raise KeyError(f"cannot find the {side.split('|')[0]} foot joint among {list(self.names)}")
            out += [ankle, toe if toe is not None else ankle]
        return tuple(out)

    def forward_axis(self) -> np.ndarray:
        """The root's local axis pointing where the character faces, inferred from the rest pose.

        ``up`` is the root-frame direction of the spine (the root child leading to the head),
        ``left - right`` the direction between the two hip children; forward = (left - right) x up,
        made orthogonal to ``up`` and unit length. For LaFAN1 this gives about (0, 1, 0).
        """
        def top_child(joint):  # the child of the root on the path to ``joint``
            while self.parents[joint] > 0:
                joint = self.parents[joint]
            return joint

        la, _, ra, _ = self.foot_joints()
        head = next((i for i, n in enumerate(self.names) if n.lower() in ("head", "neck")), None)
        left, right = self.offsets[top_child(la)], self.offsets[top_child(ra)]
        up = self.offsets[top_child(head)] if head is not None else np.array([0.0, 1.0, 0.0])
        up = up / np.linalg.norm(up)
        fwd = np.cross(left - right, up)
        fwd -= np.dot(fwd, up) * up
        return fwd / np.linalg.norm(fwd)

    def mirror_map(self) -> tuple:
        """For each joint, the index of its left/right counterpart (itself for central joints)."""
        swaps = [("Left", "Right"), ("left", "right"), ("l", "r"), ("L", "R")]
        out = []
        for i, n in enumerate(self.names):
            twin = i
            for a, b in swaps:
                for x, y in ((a, b), (b, a)):
                    if n.startswith(x) and n[len(x):]:
                        cand = y + n[len(x):]
                        if cand in self.names:
                            twin = self.names.index(cand)
                if twin != i:
                    break
            out.append(twin)
        return tuple(out)

    def to_dict(self) -> dict:
        """JSON-serialisable form (for checkpoints and caches)."""
        return {"names": list(self.names), "parents": list(self.parents),
                "offsets": np.asarray(self.offsets).tolist(), "channels": [list(c) for c in self.channels],
                "end_sites": [[p, np.asarray(o).tolist()] for p, o in self.end_sites]}

    @classmethod
    def from_dict(cls, d: dict) -> "Skeleton":
        return cls(tuple(d["names"]), tuple(int(p) for p in d["parents"]),
                   np.asarray(d["offsets"], np.float64), tuple(tuple(c) for c in d["channels"]),
                   tuple((int(p), np.asarray(o, np.float64)) for p, o in d.get("end_sites", ())))
