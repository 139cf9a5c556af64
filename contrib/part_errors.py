#!/usr/bin/env python3
"""Correspondence error per part of a generated take (issue 46).

evaluate.py measures a result against the ground truth over all vertices; a
lost limb is a few percent of them, so its figures hide which part went and
when. The family's takes (`cargo run --release -p voltrack-tools --bin family -- DIR`)
carry each vertex's part in `gt.npz` (`label`); this maps the result's base
vertices onto the truth's frame-0 vertices as evaluate.py does, leaves out
the ambiguous ones, and prints the correspondence mean / p95 / max (% of the
diagonal) over the first FRAMES frames, the worst part's mean in its worst
frame, and the frames where some part is 5 % off on average (the family
bench's "lost"). With --per-frame, one line per frame with the worst part's
mean error.

    python contrib/part_errors.py TAKE_DIR RESULT.glb [RESULT.glb ...] [--frames N] [--per-frame]

Needs numpy, scipy and trimesh (as evaluate.py), and evaluate.py at
../shared/tools/ or on PYTHONPATH.
"""
import argparse
import os
import sys

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', '..', 'shared', 'tools'))
import evaluate  # noqa: E402

LOST = 5.0  # % of the diagonal: a part this far off on average is lost


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('take')
    ap.add_argument('results', nargs='+')
    ap.add_argument('--frames', type=int, default=0, help='only the first N frames')
    ap.add_argument('--per-frame', action='store_true')
    a = ap.parse_args()
    z = np.load(os.path.join(a.take, 'gt.npz'))
    gt, ambiguous, label = z['traj'], z['ambiguous'], z['label']
    every = gt.reshape(-1, 3)
    diag = np.linalg.norm(every.max(0) - every.min(0))
    frames = min(len(gt), a.frames) if a.frames else len(gt)
    for result in a.results:
        positions, _, _ = evaluate.dynamic_mesh_from_gltf(result)
        k = min(frames, len(positions))
        _, idx = cKDTree(gt[0]).query(positions[0])
        part, keep = label[idx], ~ambiguous[idx]
        err = np.linalg.norm(positions[:k] - gt[:k, idx], axis=2) / diag * 100
        parts = [p for p in np.unique(part) if (keep & (part == p)).any()]
        per = np.array([[err[f][keep & (part == p)].mean() for p in parts] for f in range(k)])
        lost = [f for f in range(k) if per[f].max() > LOST]
        kept = err[:, keep]
        print('%s: %.3f / %.2f / %.2f, worst part %.2f, %d frames lost %s' % (
            result, kept.mean(), np.percentile(kept, 95), kept.max(), per.max(), len(lost), lost))
        if a.per_frame:
            for f in range(k):
                w = int(per[f].argmax())
                print('  %4d  part %d  %.2f' % (f, parts[w], per[f, w]))


if __name__ == '__main__':
    main()
