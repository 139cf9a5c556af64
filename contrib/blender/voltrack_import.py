# SPDX-License-Identifier: MIT OR Apache-2.0
"""Blender add-on: import a voltrack animation (GLB or PC2) with its timing.

glTF and PC2 store no frame rate Blender reads: Blender's glTF importer turns
key times into frames at the scene's current rate (24 fps by default) and
leaves the scene's range alone, so a capture made at 30 fps plays too slowly,
its keys fall between frames and the first capture lies outside the range.
voltrack records the capture rate and frame count (the GLB's scene and
animation `extras`: {"fps": ..., "frames": N}; the first line of the OBJ beside
a .pc2), and this add-on sets the scene from them:

* the scene's frame rate is the capture rate: `render.fps` / `render.fps_base`
  (30 -> 30 / 1; 29.97 -> 30 / 1.001, Blender's own NTSC preset; 12.5 ->
  25 / 2; any other rate r -> ceil(r) / (ceil(r) / r));
* capture k is shown at scene frame `frame_start + k` (k = 0 .. N-1), and the
  scene range is exactly `frame_start .. frame_start + N - 1`. `frame_start`
  defaults to 0, so scene frame k is at k / fps seconds: the glTF key times
  and the PC2's start frame 0, unshifted.

GLB: the glTF importer is called with the scene rate already set (and
`import_shading='SMOOTH'`, which also avoids Debian Blender 3.4's importer
failing on numpy >= 1.24 with `np.bool`); it converts key times with the
integer `render.fps` alone and in float32, so the keys are then snapped onto
the whole frames `frame_start + k` (k = round(time * fps)). The closing key
voltrack writes at N / fps lands on `frame_start + N`, just past the range.

PC2: the OBJ beside it (same name, .obj) is imported with its vertex order
kept (`split_mode='OFF'`) and Y up, and a Mesh Cache modifier reads the .pc2
with the same axes, frame-based, starting at `frame_start`, no interpolation
(each capture held until the next, as the GLB's STEP keys do).

Install: Edit > Preferences > Add-ons > Install... and pick this file, then
File > Import > voltrack animation (.glb/.pc2). Headless:

    blender -b --python voltrack_import.py -- FILE [--frame-start 0]
            [--empty] [--save OUT.blend]

prints one line of JSON (fps, frame_start, frame_end, shape_keys, object...).
Only Python's standard library is used to read the files.
"""

bl_info = {
    "name": "voltrack animation import",
    "author": "voltrack",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "File > Import > voltrack animation (.glb/.pc2)",
    "description": "Import a voltrack GLB or PC2 and set the scene's frame rate and range from it",
    "category": "Import-Export",
}

import base64
import json
import math
import os
import re
import struct
import sys

try:
    import bpy
    from bpy.props import IntProperty, StringProperty
    from bpy_extras.io_utils import ImportHelper
except ImportError:  # the file readers below work without Blender
    bpy = None


# ---------------------------------------------------------------------------
# File readers (standard library only)

GLB_MAGIC = b"glTF"
CHUNK_JSON = 0x4E4F534A
CHUNK_BIN = 0x004E4942
PC2_MAGIC = b"POINTCACHE2\0"


class VoltrackError(Exception):
    pass


_EMBEDDED = "data:application/octet-stream;base64,"


def read_glb(path):
    """The JSON document and the BIN chunk (bytes, or None) of a GLB file;
    of a .gltf (`voltrack convert -o NAME.gltf`), the JSON and its first
    buffer, embedded as a base64 data: URI."""
    with open(path, "rb") as f:
        data = f.read()
    if path.lower().endswith(".gltf"):
        try:
            doc = json.loads(data.decode("utf-8"))
        except ValueError as e:
            raise VoltrackError(f"{path}: not glTF JSON ({e})") from None
        buffers = doc.get("buffers") or [{}]
        uri = buffers[0].get("uri", "")
        if not uri.startswith(_EMBEDDED):
            raise VoltrackError(f"{path}: its buffer is not embedded; voltrack writes .gltf files with the buffer inside")
        return doc, base64.b64decode(uri[len(_EMBEDDED) :])
    if len(data) < 20 or data[:4] != GLB_MAGIC:
        raise VoltrackError(f"{path}: not a GLB file")
    _version, length = struct.unpack_from("<II", data, 4)
    doc, binary, offset = None, None, 12
    while offset + 8 <= min(length, len(data)):
        size, kind = struct.unpack_from("<II", data, offset)
        chunk = data[offset + 8 : offset + 8 + size]
        if kind == CHUNK_JSON and doc is None:
            doc = json.loads(chunk.decode("utf-8"))
        elif kind == CHUNK_BIN and binary is None:
            binary = chunk
        offset += 8 + size + (-size % 4)
    if doc is None:
        raise VoltrackError(f"{path}: GLB without a JSON chunk")
    return doc, binary


_COMPONENTS = {5120: "b", 5121: "B", 5122: "h", 5123: "H", 5125: "I", 5126: "f"}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def read_accessor(doc, binary, index):
    """Accessor `index` of a GLB as a list of tuples (no sparse, no normalisation)."""
    acc = doc["accessors"][index]
    width = _WIDTH[acc["type"]]
    fmt = _COMPONENTS[acc["componentType"]]
    count = acc["count"]
    if "bufferView" not in acc:
        return [(0,) * width] * count
    view = doc["bufferViews"][acc["bufferView"]]
    if view.get("buffer", 0) != 0 or binary is None:
        raise VoltrackError("only a GLB's own binary chunk is read")
    item = struct.calcsize("<" + fmt * width)
    stride = view.get("byteStride") or item
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    if stride == item:
        flat = struct.unpack_from(f"<{count * width}{fmt}", binary, start)
        return [flat[i : i + width] for i in range(0, len(flat), width)]
    return [struct.unpack_from("<" + fmt * width, binary, start + i * stride) for i in range(count)]


def weight_animation(doc):
    """(animation, sampler) of the first animation of morph weights, or (None, None)."""
    for anim in doc.get("animations", []):
        for channel in anim.get("channels", []):
            if channel.get("target", {}).get("path") == "weights":
                return anim, anim["samplers"][channel["sampler"]]
    return None, None


def glb_timing(doc, binary):
    """(fps, frames, source): from the scene's or the animation's `extras`,
    else from the key times (evenly spaced keys, one per frame)."""
    scenes = doc.get("scenes", [])
    candidates = []
    if scenes:
        candidates.append(("scene extras", scenes[doc.get("scene", 0)].get("extras")))
    anim, sampler = weight_animation(doc)
    if anim is not None:
        candidates.append(("animation extras", anim.get("extras")))
    for source, extras in candidates:
        if isinstance(extras, dict):
            fps, frames = extras.get("fps"), extras.get("frames")
            if isinstance(fps, (int, float)) and fps > 0 and isinstance(frames, int) and frames > 0:
                return float(fps), frames, source
    if sampler is None:
        raise VoltrackError("no frame rate in the file's extras and no animation to take it from")
    times = [t[0] for t in read_accessor(doc, binary, sampler["input"])]
    if len(times) < 2 or times[-1] <= times[0]:
        raise VoltrackError("no frame rate in the file's extras and too few keys to take it from")
    return (len(times) - 1) / (times[-1] - times[0]), len(times), "key times"


def read_pc2_header(path):
    """PC2 header: points, start frame, sampling, samples; checks the size."""
    with open(path, "rb") as f:
        head = f.read(32)
    if len(head) < 32 or head[:12] != PC2_MAGIC:
        raise VoltrackError(f"{path}: not a PC2 point cache")
    version, points, start, sampling, samples = struct.unpack_from("<iiffi", head, 12)
    expected = 32 + points * samples * 12
    if os.path.getsize(path) < expected:
        raise VoltrackError(f"{path}: truncated ({samples} samples of {points} points need {expected} bytes)")
    return {"version": version, "points": points, "start": start, "sampling": sampling, "samples": samples}


def read_pc2_frame(path, header, k):
    """Positions of sample k of a PC2 file, as (x, y, z) tuples."""
    n = header["points"]
    with open(path, "rb") as f:
        f.seek(32 + k * n * 12)
        flat = struct.unpack(f"<{3 * n}f", f.read(12 * n))
    return [flat[i : i + 3] for i in range(0, 3 * n, 3)]


_MESH_CACHE_LINE = re.compile(r"#\s*Mesh Cache\b.*?:\s*(\d+)\s+frames\s+at\s+([0-9.eE+-]+)\s+fps")


def obj_timing(obj_path):
    """(fps, frames, object name) from the OBJ voltrack writes beside a .pc2;
    fps and frames None when its first line does not state them."""
    fps = frames = name = None
    with open(obj_path, "r", encoding="utf-8", errors="replace") as f:
        for i, line in enumerate(f):
            if i == 0:
                m = _MESH_CACHE_LINE.match(line)
                if m:
                    frames, fps = int(m.group(1)), float(m.group(2))
            if line.startswith("o "):
                name = line[2:].strip()
                break
            if not line.startswith("#") and line.strip() and not line.startswith(("mtllib", "s ")):
                break
    return fps, frames, name


def frame_rate_settings(fps):
    """(render.fps, render.fps_base) whose ratio is `fps`: whole rates as they
    are, NTSC rates (29.97, 23.976, 59.94...) as n / 1.001 like Blender's
    presets, a ratio of whole numbers n / base (base <= 1000) as that, any
    other as ceil(fps) / (ceil(fps) / fps)."""
    if not (fps > 0 and math.isfinite(fps)):
        raise VoltrackError(f"the frame rate must be positive, not {fps}")
    whole = round(fps)
    if 1 <= whole <= 32767 and abs(fps - whole) <= 1e-6 * fps:
        return whole, 1.0
    ntsc = round(fps * 1.001)
    if 1 <= ntsc <= 32767 and abs(fps - ntsc / 1.001) <= 5e-6 * fps:
        return ntsc, 1.001
    for base in range(2, 1001):  # 12.5 -> 25 / 2, 0.5 -> 1 / 2: a base float32 holds exactly
        n = round(fps * base)
        if 1 <= n <= 32767 and abs(fps - n / base) <= 1e-6 * fps:
            return n, float(base)
    n = min(max(math.ceil(fps), 1), 32767)
    return n, n / fps


# ---------------------------------------------------------------------------
# Blender side


def set_scene_timing(scene, fps, frames, frame_start):
    scene.render.fps, scene.render.fps_base = frame_rate_settings(fps)
    scene.frame_start = frame_start
    scene.frame_end = frame_start + frames - 1
    scene.frame_set(frame_start)


def _importer(addon, name):
    """Whether bpy.ops.import_scene.<name> exists, enabling `addon` (a bundled
    add-on, on by default) if it does not yet."""
    if name in dir(bpy.ops.import_scene):  # hasattr is true of any name
        return True
    try:
        import addon_utils

        addon_utils.enable(addon, default_set=True)
    except Exception:
        return False
    return name in dir(bpy.ops.import_scene)


def _snap_action_keys(action, import_fps, file_fps, frame_start):
    """Moves every key from time * import_fps (where the glTF importer put
    it) to frame_start + round(time * file_fps); returns how far the keys
    were off whole frames before (largest |frame - round(frame)|)."""
    off = 0.0
    for fcurve in action.fcurves:
        for key in fcurve.keyframe_points:
            off = max(off, abs(key.co.x - round(key.co.x)))
            target = frame_start + round(key.co.x * file_fps / import_fps)
            shift = target - key.co.x
            key.co.x = target
            key.handle_left.x += shift
            key.handle_right.x += shift
        fcurve.update()
    return off


def importer_extensions():
    """The glTF extensions Blender's importer reads (its `extensions_managed`,
    read off its source, since it is only built inside an import), or None
    when they cannot be found out."""
    try:
        import inspect

        from io_scene_gltf2.io.imp import gltf2_io_gltf

        source = inspect.getsource(gltf2_io_gltf.glTFImporter.__init__)
    except Exception:
        return None
    listed = re.search(r"extensions_managed\s*=\s*\[(.*?)\]", source, re.S)
    return set(re.findall(r"['\"]([A-Za-z0-9_]+)['\"]", listed.group(1))) if listed else None


def unreadable_extensions(doc, readable):
    """The extensions `doc` requires that are not in `readable` (a set, or
    None for unknown: then none)."""
    if readable is None:
        return []
    return [e for e in doc.get("extensionsRequired", []) if e not in readable]


def import_glb(context, path, frame_start=0):
    doc, binary = read_glb(path)
    fps, frames, source = glb_timing(doc, binary)
    if not _importer("io_scene_gltf2", "gltf"):
        raise VoltrackError("Blender's glTF importer (add-on io_scene_gltf2) is not available")
    # Before the scene is touched: Blender 3.4's importer, for one, stops
    # with a traceback on EXT_meshopt_compression (`voltrack convert --compress`).
    missing = unreadable_extensions(doc, importer_extensions())
    if missing:
        version = ".".join(str(v) for v in bpy.app.version)
        raise VoltrackError(
            f"{path} requires {', '.join(missing)}, which Blender {version}'s glTF importer cannot read "
            "(a `voltrack convert --compress` file); for Blender, convert without --compress, "
            "or to a .pc2 (-o NAME.pc2). The scene was not changed."
        )
    scene = context.scene
    previous = (scene.render.fps, scene.render.fps_base, scene.frame_start, scene.frame_end, scene.frame_current)
    set_scene_timing(scene, fps, frames, frame_start)
    import_fps = scene.render.fps  # what the importer multiplies key times by
    before = set(bpy.data.objects)
    try:
        result = bpy.ops.import_scene.gltf(filepath=path, import_shading="SMOOTH")
    except RuntimeError as e:
        result, failure = set(), str(e).strip().splitlines()[-1:]
    else:
        failure = []
    if "FINISHED" not in result:
        scene.render.fps, scene.render.fps_base = previous[0], previous[1]
        scene.frame_start, scene.frame_end = previous[2], previous[3]
        scene.frame_set(previous[4])
        why = f": {failure[0]}" if failure else ""
        raise VoltrackError(f"Blender's glTF importer failed on {path}{why}; the scene's timing was restored")
    new = [o for o in bpy.data.objects if o not in before]
    meshes = [o for o in new if o.type == "MESH"]
    if not meshes:
        raise VoltrackError(f"{path}: no mesh imported")
    obj = next((o for o in meshes if o.data.shape_keys), meshes[0])
    shape_keys = obj.data.shape_keys
    actions = set()
    key_offset = 0.0
    if shape_keys and shape_keys.animation_data:
        ad = shape_keys.animation_data
        if ad.action:
            actions.add(ad.action)
        for track in ad.nla_tracks:
            for strip in track.strips:
                if strip.action:
                    actions.add(strip.action)
        for action in actions:
            key_offset = max(key_offset, _snap_action_keys(action, import_fps, fps, frame_start))
        for track in ad.nla_tracks:
            for strip in track.strips:
                if strip.action in actions:
                    # The stashed strip (muted, as the importer leaves it) spans the moved keys.
                    lo, hi = strip.action.frame_range
                    strip.action_frame_end = max(hi, strip.action_frame_start + 1)  # end stays past start
                    strip.action_frame_start = lo
                    strip.action_frame_end = hi
                    strip.frame_start = lo
    scene.frame_set(frame_start)
    node = _node_of(doc, obj.name)
    targets = None
    if node is not None:
        targets = len(doc["meshes"][doc["nodes"][node]["mesh"]]["primitives"][0].get("targets", []))
    return {
        "file": os.path.abspath(path),
        "format": "glb",
        "object": obj.name,
        "fps": fps,
        "timing_from": source,
        "render_fps": scene.render.fps,
        "fps_base": scene.render.fps_base,
        "frames": frames,
        "frame_start": scene.frame_start,
        "frame_end": scene.frame_end,
        "shape_keys": len(shape_keys.key_blocks) if shape_keys else 0,
        "morph_targets": targets,
        "key_offset_before_snap": key_offset,
    }


def _node_of(doc, name):
    """The mesh node called `name` (Blender renames on a clash: then the first)."""
    nodes = [i for i, node in enumerate(doc.get("nodes", [])) if "mesh" in node]
    named = [i for i in nodes if doc["nodes"][i].get("name") == name]
    return (named or nodes or [None])[0]


def import_pc2(context, path, frame_start=0):
    header = read_pc2_header(path)
    obj_path = os.path.splitext(path)[0] + ".obj"
    if not os.path.isfile(obj_path):
        raise VoltrackError(f"{path}: the mesh for the cache, {obj_path}, is missing")
    fps, frames, name = obj_timing(obj_path)
    source = "obj header"
    if fps is None:
        fps, source = context.scene.render.fps / context.scene.render.fps_base, "scene (the OBJ states no rate)"
    if frames is not None and frames != header["samples"]:
        raise VoltrackError(f"{obj_path} says {frames} frames, {path} holds {header['samples']}")
    frames = header["samples"]
    scene = context.scene
    set_scene_timing(scene, fps, frames, frame_start)
    before = set(bpy.data.objects)
    if _importer("io_scene_obj", "obj"):
        # Blender <= 3.x's Python importer; Y up in the file, as voltrack writes.
        result = bpy.ops.import_scene.obj(
            filepath=obj_path, split_mode="OFF", axis_forward="-Z", axis_up="Y", use_image_search=False
        )
    else:  # Blender 4: the C++ importer keeps the file's vertex order
        result = bpy.ops.wm.obj_import(filepath=obj_path, forward_axis="NEGATIVE_Z", up_axis="Y")
    if "FINISHED" not in result:
        raise VoltrackError(f"Blender's OBJ importer failed on {obj_path}")
    meshes = [o for o in bpy.data.objects if o not in before and o.type == "MESH"]
    if len(meshes) != 1:
        raise VoltrackError(f"{obj_path}: expected one mesh, got {len(meshes)}")
    obj = meshes[0]
    if name:
        obj.name = name
        obj.data.name = name
    if len(obj.data.vertices) != header["points"]:
        raise VoltrackError(
            f"{obj_path} has {len(obj.data.vertices)} vertices, {path} {header['points']}: the cache does not fit"
        )
    mod = obj.modifiers.new("voltrack", "MESH_CACHE")
    mod.cache_format = "PC2"
    mod.filepath = os.path.abspath(path)
    # The cache holds the OBJ's coordinates. Blender 3's importer keeps them
    # in the mesh and turns Y up into Z up by the object's rotation; should an
    # importer convert the vertices instead, the cache is read the same way.
    first = read_pc2_frame(path, header, 0)
    co = obj.data.vertices[0].co if header["points"] else None
    if co is not None and _close(co, (first[0][0], -first[0][2], first[0][1])) and not _close(co, first[0]):
        mod.forward_axis, mod.up_axis = "NEG_Z", "POS_Y"
    mod.time_mode = "FRAME"
    mod.play_mode = "SCENE"
    mod.frame_start = frame_start  # sample = scene frame - frame_start
    mod.frame_scale = 1.0
    mod.interpolation = "NONE"
    scene.frame_set(frame_start)
    return {
        "file": os.path.abspath(path),
        "format": "pc2",
        "object": obj.name,
        "fps": fps,
        "timing_from": source,
        "render_fps": scene.render.fps,
        "fps_base": scene.render.fps_base,
        "frames": frames,
        "frame_start": scene.frame_start,
        "frame_end": scene.frame_end,
        "shape_keys": 0,
        "vertices": header["points"],
        "modifier": mod.name,
    }


def _close(a, b):
    scale = max(1.0, max(abs(x) for x in b))
    return all(abs(x - y) <= 1e-5 * scale for x, y in zip(a, b))


def import_voltrack(context, path, frame_start=0):
    """Imports a voltrack .glb, or a .pc2 (or the .obj beside it), and sets the
    scene's frame rate and range; returns a summary dict."""
    ext = os.path.splitext(path)[1].lower()
    if ext in (".glb", ".gltf"):
        return import_glb(context, path, frame_start)
    if ext == ".pc2":
        return import_pc2(context, path, frame_start)
    if ext == ".obj" and os.path.isfile(os.path.splitext(path)[0] + ".pc2"):
        return import_pc2(context, os.path.splitext(path)[0] + ".pc2", frame_start)
    raise VoltrackError(f"{path}: expected a .glb, a .gltf or a .pc2 (with its .obj beside it)")


if bpy is not None:

    class IMPORT_OT_voltrack(bpy.types.Operator, ImportHelper):
        """Import a voltrack GLB or PC2 point cache and set the scene's frame rate and range from it"""

        bl_idname = "import_scene.voltrack"
        bl_label = "Import voltrack animation"
        bl_options = {"REGISTER", "UNDO"}

        filename_ext = ".glb"
        filter_glob: StringProperty(default="*.glb;*.gltf;*.pc2", options={"HIDDEN"})
        frame_start: IntProperty(
            name="First frame",
            description="Scene frame of the first capture: capture k is shown at this frame + k",
            default=0,
            min=0,
        )

        def execute(self, context):
            try:
                summary = import_voltrack(context, self.filepath, self.frame_start)
            except (VoltrackError, OSError, ValueError, struct.error) as e:
                self.report({"ERROR"}, str(e))
                return {"CANCELLED"}
            self.report(
                {"INFO"},
                f"{summary['object']}: {summary['frames']} frames at {summary['fps']:g} fps, "
                f"scene frames {summary['frame_start']}-{summary['frame_end']}",
            )
            return {"FINISHED"}

    def menu_func_import(self, context):
        self.layout.operator(IMPORT_OT_voltrack.bl_idname, text="voltrack animation (.glb/.pc2)")

    def register():
        bpy.utils.register_class(IMPORT_OT_voltrack)
        bpy.types.TOPBAR_MT_file_import.append(menu_func_import)

    def unregister():
        bpy.types.TOPBAR_MT_file_import.remove(menu_func_import)
        bpy.utils.unregister_class(IMPORT_OT_voltrack)


def main(argv=None):
    import argparse

    argv = sys.argv[sys.argv.index("--") + 1 :] if argv is None and "--" in sys.argv else (argv or [])
    parser = argparse.ArgumentParser(
        prog="blender -b --python voltrack_import.py --",
        description="Import a voltrack .glb or .pc2 and set the scene's frame rate and range.",
    )
    parser.add_argument("file", help="a voltrack .glb, or a .pc2 with its .obj beside it")
    parser.add_argument("--frame-start", type=int, default=0, help="scene frame of capture 0 (default 0)")
    parser.add_argument("--empty", action="store_true", help="start from an empty scene (no default cube)")
    parser.add_argument("--save", metavar="OUT.blend", help="save the scene there")
    args = parser.parse_args(argv)
    if args.empty:
        bpy.ops.wm.read_factory_settings(use_empty=True)
    try:
        summary = import_voltrack(bpy.context, os.path.abspath(args.file), args.frame_start)
    except (VoltrackError, OSError, ValueError, struct.error) as e:
        print(f"voltrack_import: error: {e}", file=sys.stderr)
        sys.exit(1)
    if args.save:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(args.save))
        summary["saved"] = os.path.abspath(args.save)
    print(json.dumps(summary), flush=True)
    return summary


if __name__ == "__main__":
    main()
