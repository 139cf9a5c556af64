# SPDX-License-Identifier: MIT OR Apache-2.0
"""Checks voltrack_import.py headless against voltrack GLB and PC2 files.

    blender -b --factory-startup --python-exit-code 1 \\
        --python contrib/blender/check_import.py -- FILE... [--frame-start S]
        [--expect-name NAME] [--samples M] [--operator]

For each file, in a fresh empty scene (Blender's default 24 fps, 1-250), the
add-on imports it (through File > Import's operator with --operator), then
this script asserts, against the rate and count it reads from the file itself:

* the scene's rate (render.fps / fps_base) is the file's fps (within 1e-5
  relative: 29.97 is set as Blender's 30 / 1.001);
* the scene range is exactly S .. S + N - 1 for the file's N captures;
* GLB: shape keys = morph targets + 1 (Basis), every key of the shape-key
  action on a whole frame S .. S + N; PC2: a Mesh Cache modifier on a mesh
  with the cache's vertex count;
* the object is named as the file names it (node / `o` line), and NAME if
  given;
* at scene frame S + k, for all captures (or M spread over them), the
  evaluated mesh's vertices in world space equal capture k read from the file
  with plain Python (GLB: base POSITION + sum of targets x weights at key k;
  PC2: sample k), both taken from glTF/OBJ's Y up to Blender's Z up as
  (x, y, z) -> (x, -z, y), within 1e-5 of the captures' bounding-box
  diagonal.

With --refused, each file must instead be refused (a file the importer
cannot read: a --compress GLB where Blender's importer lacks
EXT_meshopt_compression) with a message that says what to do, the scene's
objects and timing untouched.

Prints one JSON line per file and exits 1 on the first failure.
"""

import argparse
import json
import math
import os
import sys

import bpy

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import voltrack_import as vi  # noqa: E402

TOLERANCE = 1e-5  # of the diagonal


class CheckFailed(Exception):
    pass


def check(condition, message):
    if not condition:
        raise CheckFailed(message)


def z_up(p):
    return (p[0], -p[2], p[1])


def glb_captures(path):
    """Object name, morph target count and a function k -> capture k's positions."""
    doc, binary = vi.read_glb(path)
    node = next(n for n in doc["nodes"] if "mesh" in n)
    prim = doc["meshes"][node["mesh"]]["primitives"][0]
    base = vi.read_accessor(doc, binary, prim["attributes"]["POSITION"])
    targets = prim.get("targets", [])
    deltas = [None] * len(targets)
    weights = []
    _anim, sampler = vi.weight_animation(doc)
    if sampler is not None:
        flat = [w[0] for w in vi.read_accessor(doc, binary, sampler["output"])]
        stride = len(targets) * (3 if sampler.get("interpolation") == "CUBICSPLINE" else 1)
        offset = len(targets) if stride != len(targets) else 0
        weights = [flat[i + offset : i + offset + len(targets)] for i in range(0, len(flat), stride)]

    def capture(k):
        pos = [list(p) for p in base]
        for t, w in enumerate(weights[k] if weights else []):
            if w == 0.0:
                continue
            if deltas[t] is None:
                deltas[t] = vi.read_accessor(doc, binary, targets[t]["POSITION"])
            for p, d in zip(pos, deltas[t]):
                p[0] += w * d[0]
                p[1] += w * d[1]
                p[2] += w * d[2]
        return pos

    return node.get("name"), len(targets), capture


def pc2_captures(path):
    header = vi.read_pc2_header(path)
    _fps, _frames, name = vi.obj_timing(os.path.splitext(path)[0] + ".obj")
    return name, header, lambda k: vi.read_pc2_frame(path, header, k)


def evaluated_world(obj):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(depsgraph)
    mesh = ev.to_mesh()
    try:
        m = ev.matrix_world
        return [tuple(m @ v.co) for v in mesh.vertices]
    finally:
        ev.to_mesh_clear()


def file_timing(path):
    """(fps, frames) as the file states them, read here, not by the add-on."""
    if path.lower().endswith((".glb", ".gltf")):
        doc, _binary = vi.read_glb(path)
        extras = doc["scenes"][doc.get("scene", 0)]["extras"]
        return extras["fps"], extras["frames"]
    fps, frames, _name = vi.obj_timing(os.path.splitext(path)[0] + ".obj")
    return fps, frames


def check_file(path, frame_start, expect_name, samples, operator):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    before = (scene.render.fps, scene.render.fps_base, scene.frame_start, scene.frame_end)
    if operator:  # as File > Import does
        if "voltrack" not in dir(bpy.ops.import_scene):
            vi.register()
        outcome = bpy.ops.import_scene.voltrack(filepath=path, frame_start=frame_start)
        check(outcome == {"FINISHED"}, f"the import operator returned {outcome}")
    else:
        vi.import_voltrack(bpy.context, path, frame_start)
    meshes = [o for o in scene.objects if o.type == "MESH"]
    check(len(meshes) == 1, f"{len(meshes)} meshes in the scene, want 1")
    obj = meshes[0]
    fps, n = file_timing(path)
    rate = scene.render.fps / scene.render.fps_base
    check(abs(rate - fps) <= 1e-5 * fps, f"scene rate {rate} fps, file {fps}")
    check(
        (scene.frame_start, scene.frame_end) == (frame_start, frame_start + n - 1),
        f"scene range {scene.frame_start}-{scene.frame_end}, want {frame_start}-{frame_start + n - 1}",
    )
    result = {
        "file": os.path.basename(path),
        "via": "operator" if operator else "import_voltrack()",
        "object": obj.name,
        "scene_before": "%d/%g fps, %d-%d" % before,
        "fps": rate,
        "render_fps": scene.render.fps,
        "fps_base": scene.render.fps_base,
        "frame_start": scene.frame_start,
        "frame_end": scene.frame_end,
        "captures": n,
    }
    if path.lower().endswith((".glb", ".gltf")):
        name, targets, capture = glb_captures(path)
        keys = obj.data.shape_keys
        count = len(keys.key_blocks) if keys else 0
        check(count == targets + 1, f"{count} shape keys, want {targets} morph targets + Basis")
        if targets:
            action = keys.animation_data.action
            check(action is not None, "no shape-key action")
            frames = sorted({kp.co.x for fc in action.fcurves for kp in fc.keyframe_points})
            check(
                frames == [float(frame_start + k) for k in range(len(frames))] and len(frames) in (n, n + 1),
                f"keys at frames {frames[:3]}...{frames[-3:]} ({len(frames)}), want whole frames from {frame_start}",
            )
            result["key_frames"] = f"{frames[0]:g}-{frames[-1]:g} ({len(frames)} keys)"
        result["shape_keys"] = count
        result["morph_targets"] = targets
    else:
        name, header, capture = pc2_captures(path)
        mods = [m for m in obj.modifiers if m.type == "MESH_CACHE"]
        check(len(mods) == 1 and mods[0].cache_format == "PC2", "no PC2 Mesh Cache modifier")
        check(len(obj.data.vertices) == header["points"], f"{len(obj.data.vertices)} vertices, cache {header['points']}")
        check(n == header["samples"], f"{n} frames, cache {header['samples']}")
        result["shape_keys"] = len(obj.data.shape_keys.key_blocks) if obj.data.shape_keys else 0
        result["modifier"] = f"{mods[0].name}: frame_start {mods[0].frame_start:g}, axes {mods[0].forward_axis}/{mods[0].up_axis}"
    check(obj.name == name, f"object {obj.name!r}, the file names it {name!r}")
    if expect_name is not None:
        check(obj.name == expect_name, f"object {obj.name!r}, want {expect_name!r}")

    ks = list(range(n)) if samples <= 0 or samples >= n else sorted({round(i * (n - 1) / (samples - 1)) for i in range(samples)})
    wanted = {k: [z_up(p) for p in capture(k)] for k in ks}
    lo = [min(p[i] for w in wanted.values() for p in w) for i in range(3)]
    hi = [max(p[i] for w in wanted.values() for p in w) for i in range(3)]
    diagonal = math.dist(lo, hi)
    worst = (0.0, None)
    for k in ks:
        scene.frame_set(frame_start + k)
        got = evaluated_world(obj)
        check(len(got) == len(wanted[k]), f"capture {k}: {len(got)} vertices in Blender, {len(wanted[k])} in the file")
        err = max(math.dist(a, b) for a, b in zip(got, wanted[k]))
        worst = max(worst, (err, k), key=lambda e: e[0])
        check(
            err <= TOLERANCE * diagonal,
            f"capture {k} at scene frame {frame_start + k}: off by {err:.3g} = {err / diagonal:.3g} of the diagonal",
        )
    result["captures_compared"] = len(ks)
    result["max_vertex_error_of_diagonal"] = worst[0] / diagonal if diagonal else 0.0
    result["worst_capture"] = worst[1]
    return result


def check_refused(path):
    """A file this Blender's importer cannot read (a --compress GLB on
    Blender 3.4): the add-on refuses it with a message saying what to do,
    and leaves the scene as it was, objects and timing."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    timing = lambda: (scene.render.fps, scene.render.fps_base, scene.frame_start, scene.frame_end)
    before, objects = timing(), len(bpy.data.objects)
    try:
        vi.import_voltrack(bpy.context, path, 0)
    except vi.VoltrackError as e:
        message = str(e)
    else:
        raise CheckFailed("imported; want a refusal")
    check("--compress" in message and ".pc2" in message, f"the refusal does not say what to do: {message}")
    check(timing() == before, f"the scene's timing changed: {before} -> {timing()}")
    check(len(bpy.data.objects) == objects, "objects were added")
    return {"file": os.path.abspath(path), "refused": message}


def main():
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="blender -b --python check_import.py --")
    parser.add_argument("files", nargs="+")
    parser.add_argument("--frame-start", type=int, default=0)
    parser.add_argument("--expect-name")
    parser.add_argument("--samples", type=int, default=0, help="captures compared (0: all)")
    parser.add_argument("--operator", action="store_true", help="import through the registered File > Import operator")
    parser.add_argument("--refused", action="store_true", help="each file must be refused, the scene left alone")
    args = parser.parse_args(argv)
    if args.refused:
        for path in args.files:
            try:
                result = check_refused(os.path.abspath(path))
            except CheckFailed as e:
                print(f"FAIL {path}: {e}", flush=True)
                sys.exit(1)
            print("PASS " + json.dumps(result), flush=True)
        return
    for path in args.files:
        try:
            result = check_file(os.path.abspath(path), args.frame_start, args.expect_name, args.samples, args.operator)
        except (CheckFailed, vi.VoltrackError) as e:
            print(f"FAIL {path}: {e}", flush=True)
            sys.exit(1)
        print("PASS " + json.dumps(result), flush=True)


if __name__ == "__main__":
    main()
