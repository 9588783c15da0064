"""Compares C3D files written by locap with their originals, as read by ezc3d.

ezc3d (PyPI, the reference C3D reader) is a real, independent client: what it reads from
locap's output must equal what it reads from the input. Called by tests/c3d_ezc3d.rs with a
JSON list of {"original": path, "written": path, "reference": optional path} on stdin; the
reference, when given, is the file ezc3d reads instead of the original (for MIPS/SGI files,
which ezc3d cannot read, the Intel version of the same take). Prints one line per failure
and "N passed, N failed" at the end; exits 1 if any failed.
"""
import json
import sys

import ezc3d
import numpy as np


def labels(c):
    p = c["parameters"]["POINT"]
    out = list(p["LABELS"]["value"]) if "LABELS" in p else []
    n = 2
    while f"LABELS{n}" in p:
        out += list(p[f"LABELS{n}"]["value"])
        n += 1
    return [s.strip() for s in out]


def missing_mask(points, residuals):
    xyz = points[:3]
    zero = np.all(xyz == 0, axis=0)
    bad = ~np.all(np.isfinite(xyz), axis=0)
    return zero | bad | (residuals[0] < 0)


def compare(case):
    ref = ezc3d.c3d(case.get("reference") or case["original"])
    new = ezc3d.c3d(case["written"])
    problems = []
    n_points = ref["header"]["points"]["size"]
    if labels(ref)[:n_points] != labels(new)[:n_points]:
        problems.append(f"labels differ: {labels(ref)[:5]}... vs {labels(new)[:5]}...")
    if abs(ref["header"]["points"]["frame_rate"] - new["header"]["points"]["frame_rate"]) > 1e-4:
        problems.append("frame rate differs")
    p_ref, p_new = ref["data"]["points"], new["data"]["points"]
    if p_ref.shape != p_new.shape:
        problems.append(f"point array shape {p_ref.shape} vs {p_new.shape}")
    elif p_ref.size:
        m_ref = missing_mask(p_ref, ref["data"]["meta_points"]["residuals"])
        m_new = missing_mask(p_new, new["data"]["meta_points"]["residuals"])
        if np.any(m_ref != m_new):
            problems.append(f"{int(np.sum(m_ref != m_new))} samples changed between missing and present")
        scale_value = float(ref["parameters"]["POINT"]["SCALE"]["value"][0])
        tol = 1e-5 * np.maximum(1.0, np.abs(p_ref[:3])) if scale_value < 0 else abs(scale_value) * 0.51
        ok = ~(m_ref | m_new)
        diff = np.abs(p_ref[:3] - p_new[:3])
        if ok.any() and np.any((diff > tol) & ok):
            problems.append(f"point values differ by up to {np.max(np.where(ok, diff, 0)):.6g}")
    a_ref, a_new = ref["data"]["analogs"], new["data"]["analogs"]
    if a_ref.shape != a_new.shape:
        problems.append(f"analog array shape {a_ref.shape} vs {a_new.shape}")
    elif a_ref.size:
        # Channels without an ANALOG:SCALE or OFFSET entry have no defined value (ezc3d
        # reads uninitialised memory for them): compare the defined ones.
        analog = ref["parameters"]["ANALOG"]
        defined = min(len(analog["SCALE"]["value"]), len(analog["OFFSET"]["value"]), a_ref.shape[1])
        a, b = a_ref[:, :defined], a_new[:, :defined]
        if not np.allclose(a, b, rtol=1e-6, atol=1e-9, equal_nan=True):
            problems.append(f"analog values differ by up to {np.nanmax(np.abs(a - b)):.6g}")
    r_ref, r_new = ref["data"]["rotations"], new["data"]["rotations"]
    if r_ref.shape != r_new.shape:
        problems.append(f"rotation array shape {r_ref.shape} vs {r_new.shape}")
    elif r_ref.size and not np.array_equal(r_ref, r_new, equal_nan=True):
        problems.append("rotation data differs")
    return problems


def check_readable(case):
    """For originals ezc3d cannot read (or misreads, see tests/c3d_ezc3d.rs): ezc3d must read
    locap's output with locap's shape."""
    new = ezc3d.c3d(case["written"])
    shape = new["data"]["points"].shape
    want = (4, case["points"], case["frames"])
    return [] if shape == want else [f"ezc3d reads locap's file as {shape}, locap wrote {want}"]


def check_same_rejection(case):
    """For originals ezc3d rejects because of a parameter locap carries as read: ezc3d must
    reject locap's output with the same message."""

    def error(path):
        try:
            ezc3d.c3d(path)
        except Exception as e:  # ezc3d raises plain exceptions
            return str(e)
        return None

    before, after = error(case["original"]), error(case["written"])
    if before is None or before != after:
        return [f"ezc3d on the original: {before!r}; on locap's output: {after!r}"]
    return []


def check_pyc3d(case):
    """For files ezc3d rejects both as read and as written by locap: py-c3d must read the same
    points and analog samples from both."""
    import warnings

    import c3d

    warnings.simplefilter("ignore")

    def frames(path):
        with open(path, "rb") as f:
            r = c3d.Reader(f)
            pts, ana = [], []
            for _, p, a in r.read_frames():
                pts.append(p[:, :3].copy())
                ana.append(a.copy())
            return np.array(pts), np.array(ana)

    p0, a0 = frames(case["original"])
    p1, a1 = frames(case["written"])
    problems = []
    if p0.shape != p1.shape or not np.allclose(p0, p1, rtol=1e-6, atol=1e-4):
        problems.append(f"py-c3d points differ ({p0.shape} vs {p1.shape})")
    if a0.shape != a1.shape or not np.allclose(a0, a1, rtol=1e-6, atol=1e-9):
        problems.append(f"py-c3d analog differs ({a0.shape} vs {a1.shape})")
    return problems


def main():
    cases = json.load(sys.stdin)
    passed = failed = 0
    for case in cases:
        if case.get("verbose"):
            print(f"checking {case['original']}", flush=True)
        try:
            if case.get("rejected_as_read"):
                problems = check_same_rejection(case)
            elif case.get("pyc3d_only"):
                problems = check_pyc3d(case)
            elif case.get("beyond_reference"):
                problems = check_readable(case)
            else:
                problems = compare(case)
        except Exception as e:  # ezc3d raises plain exceptions on unreadable files
            problems = [f"ezc3d failed: {e}"]
        if problems:
            failed += 1
            print(f"FAIL {case['original']}: " + "; ".join(problems), flush=True)
        else:
            passed += 1
    print(f"ezc3d: {passed} passed, {failed} failed")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
