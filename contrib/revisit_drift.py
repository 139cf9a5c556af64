#!/usr/bin/env python3
"""How far a converted animation's vertices drift between visits of the same
input frame: for a sequence that shows input frame `first` again every
`period` frames (a capture played forward and back, as in docs/measurements.md),
the distance of every vertex at frame first + k * period from where it was at
frame `first`, in % of the base mesh's bounding-box diagonal (mean, p95, max).
Zero for a tracker that never drifts.

    python3 contrib/revisit_drift.py c1044.glb --period 114 --first 0 28

Reads an uncompressed GLB with one morph target per frame (voltrack
convert's default up to 256 frames, and past it when no compact basis fits).
"""
import argparse
import json
import struct
import sys

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("glb")
    ap.add_argument("--period", type=int, required=True, help="frames between visits of the same input frame")
    ap.add_argument("--first", type=int, nargs="+", default=[0], help="first frame of each input frame followed")
    args = ap.parse_args()
    data = open(args.glb, "rb").read()
    if data[:4] != b"glTF":
        sys.exit(f"{args.glb}: not a GLB")
    json_len = struct.unpack("<I", data[12:16])[0]
    doc = json.loads(data[20:20 + json_len])
    bin_start = 20 + json_len + 8
    if "EXT_meshopt_compression" in doc.get("extensionsUsed", []):
        sys.exit(f"{args.glb}: compressed; convert without --compress")

    def vec3(index):
        accessor = doc["accessors"][index]
        view = doc["bufferViews"][accessor["bufferView"]]
        start = bin_start + view.get("byteOffset", 0) + accessor.get("byteOffset", 0)
        count = accessor["count"]
        return np.frombuffer(data[start:start + 12 * count], dtype="<f4").reshape(count, 3).astype(np.float64)

    primitive = doc["meshes"][0]["primitives"][0]
    base = vec3(primitive["attributes"]["POSITION"])
    targets = primitive.get("targets", [])
    names = doc["meshes"][0].get("extras", {}).get("targetNames", [])
    if names and not names[0].startswith("frame"):
        sys.exit(f"{args.glb}: a compact basis ({names[0]}, ...), not one target per frame")
    frames = len(targets) + 1
    diagonal = np.linalg.norm(base.max(0) - base.min(0))

    def frame(f):
        return base if f == 0 else base + vec3(targets[f - 1]["POSITION"])

    print("| input frame's first frame | revisit | mean % | p95 % | max % |")
    print("|---|---|---|---|---|")
    for first in args.first:
        reference = frame(first)
        for f in range(first + args.period, frames, args.period):
            d = np.linalg.norm(frame(f) - reference, axis=1) / diagonal * 100
            print(f"| {first} | {f} | {d.mean():.2f} | {np.percentile(d, 95):.2f} | {d.max():.2f} |")


if __name__ == "__main__":
    main()
