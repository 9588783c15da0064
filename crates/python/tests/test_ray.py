"""locap.ray on a local Ray cluster: the same output files as the CLI on the same inputs, bad
takes reported as the CLI reports them and skipped."""

import os
import re
import shutil
from pathlib import Path

import pytest

import locap
from conftest import EXAMPLE, run_cli

ray = pytest.importorskip("ray") if not os.environ.get("CI") else __import__("ray")
import locap.ray as locap_ray  # noqa: E402


@pytest.fixture(scope="module")
def cluster():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def tree(root: Path) -> dict:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def cli_failures(stderr: str) -> set:
    # `locap: path: reason` lines, warnings left out.
    return {line[len("locap: "):] for line in stderr.splitlines()
            if line.startswith("locap: ") and ": warning: " not in line and not line.startswith("locap: error:")}


@pytest.fixture()
def takes(shared, tmp_path):
    """Real takes from several folders (vendor files with analog channels and force plates,
    the c3d.org broken samples, BTK's empty file, a folder with a UTF-8 name) plus one file
    that is not C3D at all, in a folder of links so the run finishes in well under a minute."""
    root = tmp_path / "in"
    for sub in ("c3d-vendors", "c3d-conformance/btk", "c3d-conformance/sample_19",
                "c3d-conformance/sample_12", "c3d-conformance/sample_05", "c3d-conformance/sample_31"):
        for path in (shared / sub).rglob("*"):
            if path.is_file() and path.stat().st_size < 3_000_000:
                link = root / sub / path.relative_to(shared / sub)
                link.parent.mkdir(parents=True, exist_ok=True)
                link.symlink_to(path)
    (root / "not-c3d.c3d").write_bytes(b"this is not a C3D file\n" * 40)
    return root


def test_ray_clean_writes_what_locap_clean_writes(cli, cluster, takes, tmp_path):
    done = run_cli(cli, "clean", takes, "-o", tmp_path / "cli", check=False)
    assert done.returncode == 1, "the bad takes fail the CLI run"
    rows = locap_ray.clean([takes], tmp_path / "ray")
    assert tree(tmp_path / "ray") == tree(tmp_path / "cli")
    failed = {r["error"] for r in rows if not r["ok"]}
    assert failed == cli_failures(done.stderr)
    assert any(str(takes / "not-c3d.c3d") in e for e in failed)
    good = [r for r in rows if r["ok"]]
    assert len(good) >= 5 and all(Path(r["output"]).is_file() for r in good)
    assert all({"gaps", "filled_samples", "still_missing", "seconds"} <= set(r) for r in good)


def test_ray_solve_and_label_match_the_cli(cli, cluster, tmp_path):
    folder = tmp_path / "takes"
    (folder / "a").mkdir(parents=True)
    (folder / "b").mkdir()
    shutil.copy(EXAMPLE, folder / "a" / "take.c3d")
    run_cli(cli, "convert", EXAMPLE, folder / "b" / "take.trc")
    run_cli(cli, "solve", folder, "-o", tmp_path / "cli", "--markers-out", tmp_path / "cli-markers")
    rows = locap_ray.solve(folder, tmp_path / "ray", markers_out=tmp_path / "ray-markers")
    assert all(r["ok"] for r in rows) and len(rows) == 2
    assert tree(tmp_path / "ray") == tree(tmp_path / "cli")
    assert tree(tmp_path / "ray-markers") == tree(tmp_path / "cli-markers")

    raw = tmp_path / "raw"
    raw.mkdir()
    run_cli(cli, "unlabel", EXAMPLE, "-o", raw / "shuffled.c3d", "--ghosts", "0", "--drop", "none")
    run_cli(cli, "label", raw, "--template", EXAMPLE, "-o", tmp_path / "cli-labeled")
    rows = locap_ray.label(raw, tmp_path / "ray-labeled", template=EXAMPLE)
    assert [r["ok"] for r in rows] == [True]
    assert tree(tmp_path / "ray-labeled") == tree(tmp_path / "cli-labeled")


def test_expand_and_names_follow_the_cli(tmp_path):
    (tmp_path / "d" / "x").mkdir(parents=True)
    (tmp_path / "d" / "x" / "t.C3D").write_bytes(b"")
    (tmp_path / "d" / "t.c3d").write_bytes(b"")
    (tmp_path / "d" / "notes.txt").write_bytes(b"")
    (tmp_path / "d" / "loop").symlink_to(tmp_path / "d")
    files, failures = locap_ray.expand([tmp_path / "d", tmp_path / "d" / "t.c3d", tmp_path / "nope"], ["c3d"])
    assert files == [str(tmp_path / "d" / "t.c3d"), str(tmp_path / "d" / "x" / "t.C3D")]
    assert len(failures) == 1 and re.match(rf"{tmp_path}/nope: cannot open: .* \(os error 2\)", failures[0])
    assert locap_ray.output_paths(["data/hands/x.c3d", "data/c3d/s37/x.c3d"], "out") == [
        "out/hands/x.c3d", "out/c3d/s37/x.c3d"]
    assert locap_ray.output_paths(["a/b/take.c3d"], "o", "trc") == ["o/take.trc"]
    with pytest.raises(ValueError):
        locap_ray.clean([tmp_path / "d"], tmp_path / "d")
    with pytest.raises(locap.Error):
        locap_ray.clean([tmp_path / "nope"], tmp_path / "out")
