"""Import a BVH file with Blender's own BVH importer and dump every bone's world position per frame.

    blender --background --factory-startup --python-exit-code 1 \\
        --python tests/blender_harness.py -- IN.bvh OUT.json

Runs inside Blender's Python (``bpy``), not in the project's environment.  The import settings make
Blender's world coordinates map back to the file's without any scaling:

* ``global_scale=1``: one Blender unit is one unit of the file (cm for LaFAN1 / CMU, 1/128 unit for the
  CMU salsa files), so positions come back in the file's unit;
* ``axis_forward='-Z', axis_up='Y'``: the file is Y-up.  Blender is Z-up, and the importer applies
  ``axis_conversion(from_forward='-Z', from_up='Y')``, the rotation ``(x, y, z)_file -> (x, -z, y)_blender``,
  then bakes it into the armature (``transform_apply``).  The harness undoes it explicitly with
  :func:`blender_to_file`: ``(x, y, z)_blender -> (x, z, -y)_file``;
* ``rotate_mode='NATIVE'``: each pose bone keeps the Euler order of its BVH channels;
* ``use_fps_scale=False``, ``frame_start=1``: file frame ``k`` (0-based) is keyed on scene frame ``1 + k``
  (linear interpolation, so evaluating at integer frames gives the keyed values).

What Blender builds from a BVH hierarchy: one bone per joint, named after the joint (Blender shortens
names longer than 63 bytes; every bone name is listed in the output), whose *head* is the joint's
position (the root bone's head is the root joint).  A bone's tail is its End Site (joints with an End
Site), its only child's head, or the mean of its children's heads; bones shorter than 1e-3 get a
made-up tail.  So heads are compared with joint positions and only End-Site tails with End Sites.

Output JSON::

    {"blender": "3.4.1", "frame_start": 1, "num_frames": T,
     "bones": [name, ...] (B), "parents": [parent name or null, ...] (B),
     "heads": (T, B, 3) nested lists, world bone heads in the file's axes and unit,
     "tails": (T, B, 3) nested lists, world bone tails likewise}

Errors print one line ``blender_harness: <problem>`` and exit with status 1.
"""
import builtins
import json
import os
import sys


def blender_to_file(v):
    """Blender world (Z-up) -> the BVH file's axes (Y-up): inverse of (x, y, z) -> (x, -z, y)."""
    return [float(v[0]), float(v[2]), -float(v[1])]


def _patch_open(module) -> None:
    """Debian's Blender 3.4 importer opens the file with mode 'rU', which Python 3.11 rejects."""
    def open_without_u(file, mode="r", *args, **kwargs):
        return builtins.open(file, mode.replace("U", "") or "r", *args, **kwargs)
    module.open = open_without_u      # a module global shadows the builtin inside the importer


def import_bvh(path: str):
    """Import ``path`` into an empty scene; returns the armature object."""
    import bpy
    from io_anim_bvh import import_bvh as importer
    _patch_open(importer)
    before = set(bpy.data.objects)
    result = bpy.ops.import_anim.bvh(
        filepath=path, target="ARMATURE", global_scale=1.0, frame_start=1, use_fps_scale=False,
        update_scene_fps=True, update_scene_duration=True, use_cyclic=False, rotate_mode="NATIVE",
        axis_forward="-Z", axis_up="Y")
    if result != {"FINISHED"}:
        raise RuntimeError(f"{path}: Blender's BVH import returned {sorted(result)}")
    new = [o for o in bpy.data.objects if o not in before and o.type == "ARMATURE"]
    if len(new) != 1:
        raise RuntimeError(f"{path}: expected one imported armature, found {len(new)}")
    return new[0]


def dump(path: str, out_path: str) -> None:
    import bpy
    arm = import_bvh(path)
    scene = bpy.context.scene
    keys = {int(round(k.co[0])) for fc in arm.animation_data.action.fcurves for k in fc.keyframe_points}
    first, last = min(keys), max(keys)          # one key per file frame on every curve
    bones = [b.name for b in arm.data.bones]
    parents = [b.parent.name if b.parent else None for b in arm.data.bones]
    heads, tails = [], []
    for frame in range(first, last + 1):
        scene.frame_set(frame)
        ev = arm.evaluated_get(bpy.context.evaluated_depsgraph_get())
        world = ev.matrix_world
        pbs = [ev.pose.bones[n] for n in bones]
        heads.append([blender_to_file(world @ pb.head) for pb in pbs])
        tails.append([blender_to_file(world @ pb.tail) for pb in pbs])
    out = {"blender": bpy.app.version_string, "frame_start": first, "num_frames": len(heads),
           "bones": bones, "parents": parents, "heads": heads, "tails": tails}
    tmp = out_path + ".tmp"
    with builtins.open(tmp, "w") as fh:
        json.dump(out, fh)
    os.replace(tmp, out_path)


def main(argv) -> int:
    args = argv[argv.index("--") + 1:] if "--" in argv else []
    if len(args) != 2:
        print("blender_harness: usage: blender --background --python blender_harness.py -- IN.bvh OUT.json")
        return 1
    if not os.path.isfile(args[0]):
        print(f"blender_harness: {args[0]}: file not found")
        return 1
    try:
        dump(os.path.abspath(args[0]), os.path.abspath(args[1]))
    except Exception as e:      # one line, no traceback: the test shows it as the failure reason
        # Blender's operator errors hold a whole traceback: keep its last line (before "Location: ...")
        last = ([ln for ln in str(e).strip().splitlines() if not ln.startswith("Location:")] or [""])[-1]
        print(f"blender_harness: {args[0]}: {type(e).__name__}: {last}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
