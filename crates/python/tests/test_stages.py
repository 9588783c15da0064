"""The stages on the shipped example take: the same output files as the CLI's commands."""

import json

import numpy as np
import pytest

import locap
from conftest import EXAMPLE, REPO, run_cli


def test_clean_fills_the_example_and_writes_the_bytes_of_locap_clean(cli, tmp_path):
    take = locap.read(EXAMPLE)
    cleaned = locap.clean(take)
    assert cleaned.positions.shape == take.positions.shape
    report = cleaned.report
    assert report["gaps"] > 0 and report["filled_samples"] > 0
    assert np.isnan(cleaned.positions).sum() < np.isnan(take.positions).sum()
    assert cleaned.filled.sum() >= report["filled_samples"]
    # Filled samples were missing; captured ones are kept unless they were outliers.
    was_missing = np.isnan(take.positions).all(axis=2)
    assert (cleaned.filled[was_missing] | np.isnan(cleaned.positions[was_missing]).all(axis=1)).all()
    assert "LOCAP" in cleaned.parameters and cleaned.parameters["LOCAP"]["METHOD"]
    cleaned.write(tmp_path / "py.c3d")
    run_cli(cli, "clean", EXAMPLE, "-o", tmp_path / "cli.c3d")
    assert (tmp_path / "py.c3d").read_bytes() == (tmp_path / "cli.c3d").read_bytes()
    # The input is untouched: cleaning returns a new take.
    assert np.isnan(take.positions).sum() == np.isnan(locap.read(EXAMPLE).positions).sum()


@pytest.mark.parametrize(
    "options,flags",
    [
        ({"method": "linear", "outliers": False}, ["--method", "linear", "--outliers", "off"]),
        ({"method": "auto", "neighbours": 4}, ["--method", "auto", "--neighbours", "4"]),
        ({"method": "neural"}, ["--method", "neural"]),
    ],
)
def test_clean_options_match_the_cli_flags(cli, tmp_path, options, flags):
    locap.clean(locap.read(EXAMPLE), **options).write(tmp_path / "py.c3d")
    run_cli(cli, "clean", EXAMPLE, "-o", tmp_path / "cli.c3d", *flags)
    assert (tmp_path / "py.c3d").read_bytes() == (tmp_path / "cli.c3d").read_bytes()


def test_clean_refuses_values_that_cannot_make_sense():
    take = locap.read(EXAMPLE)
    for bad in ({"method": "magic"}, {"neighbours": 0}, {"ranking": "x"}, {"body_threshold_m_s2": -1.0},
                {"models": ["m.locapnn"]}):
        with pytest.raises(ValueError):
            locap.clean(take, **bad)
    with pytest.raises(locap.Error) as err:
        locap.clean(take, method="neural", models=["no/such/model.locapnn"])
    assert "no/such/model.locapnn" in str(err.value)


def test_solve_gives_the_motion_and_files_of_locap_solve(cli, tmp_path):
    take = locap.read(EXAMPLE)
    motion = locap.solve(take)
    joints = len(motion.joint_names)
    assert motion.frame_count == take.frame_count and motion.rate_hz == take.rate_hz
    assert motion.rotations.shape == (take.frame_count, joints, 4)
    assert np.allclose(np.linalg.norm(motion.rotations, axis=2), 1.0)
    assert motion.offsets_mm.shape == (joints, 3)
    assert motion.root_translation_mm.shape == (take.frame_count, 3)
    parents = motion.parents
    assert parents[0] == -1 and all(0 <= p < j for j, p in enumerate(parents) if j > 0)
    glob = motion.global_positions_mm()
    assert glob.shape == (take.frame_count, joints, 3)
    assert np.allclose(glob[:, 0], motion.root_translation_mm)
    motion.write_bvh(tmp_path / "py.bvh")
    motion.cleaned.write(tmp_path / "py.c3d")
    run_cli(cli, "solve", EXAMPLE, "-o", tmp_path / "cli.bvh", "--markers-out", tmp_path / "cli.c3d")
    assert (tmp_path / "py.bvh").read_bytes() == (tmp_path / "cli.bvh").read_bytes()
    assert (tmp_path / "py.c3d").read_bytes() == (tmp_path / "cli.c3d").read_bytes()


def test_solve_methods_match_locap_solve(cli, tmp_path):
    """``method="network"``, ``"ik"`` and ``"refine"`` write what ``locap solve --method`` writes, and a
    method that does not exist is an error naming the choices."""
    take = locap.read(EXAMPLE)
    for method in ("network", "ik", "refine"):
        locap.solve(take, method=method).write_bvh(tmp_path / f"py-{method}.bvh")
        run_cli(cli, "solve", EXAMPLE, "--method", method, "-o", tmp_path / f"cli-{method}.bvh")
        assert (tmp_path / f"py-{method}.bvh").read_bytes() == (tmp_path / f"cli-{method}.bvh").read_bytes()
    # The two solve differently (the network's rotations pull the refined fit).
    assert (tmp_path / "py-ik.bvh").read_bytes() != (tmp_path / "py-refine.bvh").read_bytes()
    with pytest.raises(ValueError, match="one of auto, network, ik, refine"):
        locap.solve(take, method="magic")
    # A layout without a skeleton cannot be solved kinematically: the error names the file.
    plain = REPO / "crates" / "synth" / "layouts" / "cmu41.toml"
    with pytest.raises(locap.Error, match="cmu41.toml.*skeleton"):
        locap.solve(take, method="ik", layout=plain)


def test_solve_takes_an_ensemble_as_locap_solve_does(cli, tmp_path):
    """``model=[...]`` is ``locap solve --model A --model B ...``: the built-in solver is the three
    body models as one, and a model of another marker set cannot join (the error names it)."""
    take = locap.read(EXAMPLE)
    models = [REPO / "models" / m for m in ("solver-cmu41-v3.locapsv", "solver-cmu41-v2.locapsv", "solver-cmu41.locapsv")]
    locap.solve(take, method="network", model=models).write_bvh(tmp_path / "py.bvh")
    run_cli(cli, "solve", EXAMPLE, "--method", "network", "-o", tmp_path / "cli.bvh")
    assert (tmp_path / "py.bvh").read_bytes() == (tmp_path / "cli.bvh").read_bytes()
    locap.solve(take, method="network", model=str(models[0])).write_bvh(tmp_path / "one.bvh")
    assert (tmp_path / "one.bvh").read_bytes() != (tmp_path / "cli.bvh").read_bytes()
    with pytest.raises(locap.Error, match="solver-hand-left.locapsv"):
        locap.solve(take, model=[models[0], REPO / "models" / "solver-hand-left.locapsv"])


def test_label_names_a_shuffled_take_as_locap_label(cli, tmp_path):
    raw = tmp_path / "raw.c3d"
    run_cli(cli, "unlabel", EXAMPLE, "-o", raw, "--ghosts", "0", "--drop", "none", "--seed", "3")
    labeled = locap.label(locap.read(raw), EXAMPLE)
    template = locap.read(EXAMPLE)
    assert labeled.labels == [l for l in template.labels if not l.startswith("*")]
    assert labeled.report["labeled_fraction"] > 0.9
    labeled.write(tmp_path / "py.c3d")
    run_cli(cli, "label", raw, "--template", EXAMPLE, "-o", tmp_path / "cli.c3d")
    assert (tmp_path / "py.c3d").read_bytes() == (tmp_path / "cli.c3d").read_bytes()


def test_bench_fill_reports_the_table_of_the_cli(cli, tmp_path):
    report = locap.bench_fill([EXAMPLE], seed=4, no_neural=True, max_gap=120)
    run_cli(cli, "bench", "fill", EXAMPLE, "--seed", "4", "--no-neural", "--max-gap", "120",
            "--json", tmp_path / "cli.json")
    theirs = json.loads((tmp_path / "cli.json").read_text())
    assert "OMPE mm" in report["table"]
    assert report["hidden_samples"] == theirs["hidden_samples"] > 0
    assert report["hidden_gaps"] == theirs["hidden_gaps"]
    ours = {m["method"]: m for m in report["methods"]}
    assert set(ours) == {m["method"] for m in theirs["methods"]}
    for m in theirs["methods"]:
        for key, value in m.items():
            # Everything but the measured speed is the same computation on the same gaps.
            if key in ("seconds", "frames_per_second"):
                continue
            assert ours[m["method"]][key] == value, (m["method"], key)
