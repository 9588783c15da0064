"""Reads one C3D file with ezc3d (the reference reader) and prints what it found as JSON, for
tests/c3d_long_takes.rs to compare with what locap wrote.

Usage: ezc3d_read_back.py FILE.c3d FRAME_STEP GROUP:NAME...

Prints {"shape", "missing", "sum", "frames": {index: [[x, y, z], ...]}, "labels",
"strings": {"GROUP:NAME": [...]}, "point_frames"}: the point array's shape, the number of
missing samples (NaN in ezc3d), the sum of every present coordinate (exact when the test's
coordinates are multiples of 1/4), the points of every FRAME_STEP-th frame and of the last
frame, the point labels, and the strings of each GROUP:NAME parameter followed by those of
NAME2, NAME3, ... (the C3D continuation convention).
"""
import json
import sys

import ezc3d
import numpy as np


def continued(params, group, name):
    out = []
    g = params.get(group, {})
    if name in g:
        out += list(g[name]["value"])
    n = 2
    while f"{name}{n}" in g:
        out += list(g[f"{name}{n}"]["value"])
        n += 1
    return [s.rstrip(" \0") for s in out]


def main():
    path, step = sys.argv[1], int(sys.argv[2])
    c = ezc3d.c3d(path)
    points = c["data"]["points"]
    xyz = points[:3]
    n = xyz.shape[2]
    picked = sorted(set(range(0, n, step)) | ({n - 1} if n else set()))
    out = {
        "shape": list(points.shape),
        "missing": int(np.isnan(xyz[0]).sum()),
        "sum": float(np.nansum(xyz, dtype=np.float64)),
        "frames": {str(f): [[None if np.isnan(v) else float(v) for v in xyz[:, m, f]] for m in range(xyz.shape[1])] for f in picked},
        "labels": continued(c["parameters"], "POINT", "LABELS"),
        "strings": {},
        "point_frames": [int(v) for v in c["parameters"]["POINT"]["FRAMES"]["value"]],
    }
    for spec in sys.argv[3:]:
        group, name = spec.split(":")
        out["strings"][spec] = continued(c["parameters"], group, name)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
