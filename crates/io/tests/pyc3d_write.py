"""py-c3d side of crates/io/tests/c3d_crosscheck_pyc3d.rs.

    pyc3d_write.py write DIR   writes DIR/int.c3d and DIR/float.c3d with py-c3d's c3d.Writer,
                               and DIR/expected.json with what they hold
    pyc3d_write.py read FILE   prints, as JSON, what py-c3d's c3d.Reader reads from FILE

Synthetic content: 4 markers over 60 frames at 100 Hz, 2 analog channels at 400 Hz (4
samples per channel per frame). Some samples are missing (py-c3d convention: residual -1; its
writer then leaves whatever coordinates the previous frame had in its buffer, so missing
samples do not have zero coordinates). Residuals and camera masks are set on valid samples.
"""

import json
import math
import os
import sys

import c3d
import numpy as np

MARKERS = ["LFHD", "RFHD", "Subj:LANK", "C7"]
FRAMES = 60
RATE = 100.0
CHANNELS = ["EMG1", "Force Z"]
ANALOG_PER_FRAME = 4  # samples per channel per 3D frame


def missing(frame, marker):
    # marker 1: a gap in the middle; marker 3: first and last frames
    return (marker == 1 and 10 <= frame < 15) or (marker == 3 and frame in (0, FRAMES - 1))


def position(frame, marker):
    t = frame / RATE
    return [
        -1500.0 + 700.0 * marker + 120.0 * math.sin(2.0 * t + marker),
        250.0 * math.cos(3.0 * t) - 100.0 * marker,
        900.0 + 400.0 * marker + 50.0 * math.sin(5.0 * t),
    ]


def analog_value(frame, sample, channel, as_int):
    k = frame * ANALOG_PER_FRAME + sample
    v = 1800.0 * math.sin(0.05 * k + channel) + 37.0 * channel
    return int(round(v)) if as_int else float(np.float32(v / 7.0))


def write(directory):
    expected = {"markers": MARKERS, "frames": FRAMES, "rate": RATE, "channels": CHANNELS,
                "analog_per_frame": ANALOG_PER_FRAME, "files": {}}
    for name, scale in (("int", 0.1), ("float", -1.0)):
        is_int = scale > 0
        writer = c3d.Writer(point_rate=RATE, analog_rate=RATE * ANALOG_PER_FRAME, point_scale=scale)
        writer.set_point_labels(MARKERS)
        writer.set_analog_labels(CHANNELS)
        points_expected, residuals_expected, cameras_expected, analog_expected = [], [], [], []
        frames = []
        for f in range(FRAMES):
            points = np.zeros((len(MARKERS), 5), np.float32)
            row, res_row, cam_row = [], [], []
            for m in range(len(MARKERS)):
                if missing(f, m):
                    points[m] = [0.0, 0.0, 0.0, -1.0, -1.0]
                    row.append(None)
                    res_row.append(None)
                    cam_row.append(None)
                    continue
                p = position(f, m)
                residual = 0.3 + 0.2 * m + 0.01 * (f % 5)  # mm
                cameras = 1 + 2 * m + 16 * (f % 3)  # < 128: the sign bit means "missing"
                points[m] = p + [residual, cameras]
                row.append(p)
                step = abs(scale)
                res_row.append(float(np.rint(np.float32(residual) / step)) * step)
                cam_row.append(cameras)
            analog = np.zeros((len(CHANNELS), ANALOG_PER_FRAME), np.float64)
            for s in range(ANALOG_PER_FRAME):
                for c in range(len(CHANNELS)):
                    v = analog_value(f, s, c, is_int)
                    analog[c, s] = v
                    analog_expected.append(v)  # sub-sample major, channel minor, as stored
            frames.append((points, analog))
            points_expected.append(row)
            residuals_expected.append(res_row)
            cameras_expected.append(cam_row)
        writer.add_frames(frames)
        path = os.path.join(directory, name + ".c3d")
        with open(path, "wb") as handle:
            writer.write(handle)
        expected["files"][name] = {"path": path, "scale": scale, "points": points_expected,
                                   "residuals": residuals_expected, "cameras": cameras_expected,
                                   "analog": analog_expected}
    with open(os.path.join(directory, "expected.json"), "w") as handle:
        json.dump(expected, handle)


def read(path):
    with open(path, "rb") as handle:
        reader = c3d.Reader(handle)
        labels = [label.strip() for label in reader.point_labels]
        frames = []
        for _, points, _ in reader.read_frames():
            frames.append([None if p[3] < 0 else [float(p[0]), float(p[1]), float(p[2]), float(p[3])]
                           for p in points])
        json.dump({"labels": labels, "rate": float(reader.point_rate), "first_frame": int(reader.first_frame),
                   "frames": frames}, sys.stdout)


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "write":
        write(sys.argv[2])
    elif len(sys.argv) == 3 and sys.argv[1] == "read":
        read(sys.argv[2])
    else:
        sys.exit(__doc__)
