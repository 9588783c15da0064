"""Compares the parameters and header events ezc3d reads from C3D files before and after
`locap convert a.c3d b.c3d` (tests/c3d_ezc3d.rs). Called with a JSON list of {"original",
"written"} on stdin; prints one line per difference and "N passed, N failed"; exits 1 if any
failed. Every parameter must read the same except the data start blocks (`DATA_START` of
any group), which locap recomputes; the data themselves are compared by ezc3d_compare.py.
"""
import json
import sys

import ezc3d


def flat(c):
    out = {}
    for group, params in c["parameters"].items():
        if not isinstance(params, dict):
            continue
        for name, p in params.items():
            if isinstance(p, dict) and "value" in p and name != "DATA_START":
                v = p["value"]
                out[(group, name)] = (p.get("type"), v.tolist() if hasattr(v, "tolist") else list(v))
    return out


def compare(case):
    a, b = ezc3d.c3d(case["original"]), ezc3d.c3d(case["written"])
    fa, fb = flat(a), flat(b)
    problems = [f"{k[0]}:{k[1]} {fa.get(k)} -> {fb.get(k)}"[:300] for k in sorted(set(fa) | set(fb)) if fa.get(k) != fb.get(k)]
    if str(a["header"]["events"]) != str(b["header"]["events"]):
        problems.append("header events differ")
    return problems


def main():
    passed = failed = 0
    for case in json.load(sys.stdin):
        try:
            problems = compare(case)
        except Exception as e:  # ezc3d raises plain exceptions on unreadable files
            problems = [f"ezc3d failed: {e}"]
        if problems:
            failed += 1
            print(f"FAIL {case['original']}: " + "; ".join(problems), flush=True)
        else:
            passed += 1
    print(f"ezc3d parameters: {passed} passed, {failed} failed")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
