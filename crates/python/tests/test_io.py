"""Reading and writing takes: the same bytes as `locap convert`, NaN where samples are
missing, errors that name the file."""

import math
import threading

import numpy as np
import pytest

import locap
from conftest import EXAMPLE, run_cli


def test_read_gives_positions_in_mm_with_nan_where_missing():
    take = locap.read(EXAMPLE)
    assert take.positions.shape == (take.frame_count, take.marker_count, 3)
    assert take.positions.dtype == np.float64
    assert take.rate_hz == 120.0
    assert take.up_axis in ("Y", "Z")
    assert len(take.labels) == take.marker_count
    missing = np.isnan(take.positions)
    # A sample is missing as a whole, never one coordinate of it.
    assert (missing.all(axis=2) == missing.any(axis=2)).all()
    # The example is a cut of CMU 01_01 with real occlusion gaps.
    assert 0 < missing.all(axis=2).sum() < missing.shape[0] * missing.shape[1]
    assert np.isnan(take.residuals_mm[missing.all(axis=2)]).all()
    assert not take.filled.any()
    params = take.parameters
    assert params["POINT"]["RATE"] == pytest.approx(120.0)
    assert params["POINT"]["LABELS"][: take.marker_count] == take.labels


def test_nan_mask_matches_the_cli_info(cli, tmp_path):
    # `locap info --json` counts missing samples per marker from the same file.
    import json

    info = json.loads(run_cli(cli, "info", EXAMPLE, "--json").stdout)
    take = locap.read(EXAMPLE)
    missing = np.isnan(take.positions).all(axis=2).sum(axis=0)
    markers = info["gaps"]["markers"]
    assert [m["name"] for m in markers] == take.labels
    assert [m["missing_frames"] for m in markers] == missing.tolist()


@pytest.mark.parametrize("ext", ["c3d", "trc", "csv"])
def test_writing_a_read_take_gives_the_bytes_of_locap_convert(cli, tmp_path, ext):
    # Same file name: TRC's header carries it.
    (tmp_path / "py").mkdir()
    (tmp_path / "cli").mkdir()
    ours, theirs = tmp_path / "py" / f"take.{ext}", tmp_path / "cli" / f"take.{ext}"
    locap.read(EXAMPLE).write(ours)
    run_cli(cli, "convert", EXAMPLE, theirs)
    assert ours.read_bytes() == theirs.read_bytes()


def test_c3d_round_trips_of_vendor_files_match_the_cli(cli, shared, tmp_path):
    files = sorted((shared / "c3d-vendors").glob("*.c3d"))
    assert files
    compared = 0
    for i, path in enumerate(files):
        try:
            take = locap.read(path)
        except locap.Error:
            assert run_cli(cli, "convert", path, tmp_path / f"cli{i}.c3d", check=False).returncode != 0
            continue
        take.write(tmp_path / f"py{i}.c3d")
        run_cli(cli, "convert", path, tmp_path / f"cli{i}.c3d")
        assert (tmp_path / f"py{i}.c3d").read_bytes() == (tmp_path / f"cli{i}.c3d").read_bytes(), path
        compared += 1
    assert compared >= 5


def test_a_take_from_numpy_keeps_its_nan_mask_through_c3d_trc_and_csv(tmp_path):
    rng = np.random.default_rng(3)
    positions = rng.normal(0.0, 500.0, size=(50, 4, 3)).round(1)
    positions[10:20, 1] = np.nan
    positions[0, 3] = np.nan
    positions[49, 0] = np.nan
    take = locap.Take(positions, ["A", "B", "Sub:C", "D"], 100.0, first_frame=5, up_axis="Y")
    assert take.labels == ["A", "B", "Sub:C", "D"]
    for ext in ("c3d", "trc", "csv"):
        path = tmp_path / f"t.{ext}"
        take.write(path)
        back = locap.read(path)
        assert back.frame_count == 50 and back.marker_count == 4
        assert (np.isnan(back.positions) == np.isnan(positions)).all(), ext
        ok = ~np.isnan(positions)
        assert np.allclose(back.positions[ok], positions[ok], atol=0.01), ext
        assert back.rate_hz == pytest.approx(100.0)


def test_assigned_positions_are_written(tmp_path):
    take = locap.read(EXAMPLE)
    positions = take.positions
    positions[:, 0] = np.nan
    take.positions = positions
    take.write(tmp_path / "edited.c3d")
    back = locap.read(tmp_path / "edited.c3d")
    assert np.isnan(back.positions[:, 0]).all()
    assert (np.isnan(back.positions[:, 1:]) == np.isnan(positions[:, 1:])).all()
    with pytest.raises(ValueError):
        take.positions = positions[:, :3]


def test_bad_files_raise_locap_error_naming_the_path(tmp_path):
    garbage = tmp_path / "garbage.c3d"
    garbage.write_bytes(b"\x02P" + bytes(range(256)) * 3)
    with pytest.raises(locap.Error) as err:
        locap.read(garbage)
    assert str(err.value).startswith(f"{garbage}: ")
    missing = tmp_path / "missing.c3d"
    with pytest.raises(locap.Error) as err:
        locap.read(missing)
    assert str(missing) in str(err.value)
    truncated = tmp_path / "truncated.trc"
    truncated.write_text("PathFileType\t4\t(X/Y/Z)\tx.trc\n")
    with pytest.raises(locap.Error) as err:
        locap.read(truncated)
    assert str(truncated) in str(err.value)
    with pytest.raises(locap.Error) as err:
        locap.read(EXAMPLE).write(tmp_path / "x.bvh")
    assert "unknown output format" in str(err.value)


def test_bad_conformance_files_give_the_cli_message(cli, shared, tmp_path):
    # The deliberately broken c3d.org samples and BTK's empty file: the same `path: reason`
    # as the CLI prints for them.
    bad = 0
    for path in sorted((shared / "c3d-conformance").rglob("*")):
        if path.suffix.lower() != ".c3d" or path.stat().st_size > 200_000:
            continue
        try:
            locap.read(path)
        except locap.Error as err:
            done = run_cli(cli, "info", path, check=False)
            assert done.returncode == 1
            assert f"locap: {err}" in done.stderr, path
            bad += 1
    assert bad >= 1


def test_the_interpreter_is_released_while_cleaning():
    ticks = 0
    stop = threading.Event()

    def count():
        nonlocal ticks
        while not stop.is_set():
            ticks += 1

    thread = threading.Thread(target=count)
    thread.start()
    try:
        before = ticks
        for _ in range(3):
            locap.clean(locap.read(EXAMPLE))
        during = ticks - before
    finally:
        stop.set()
        thread.join()
    assert during > 1000


def test_the_package_has_stubs_and_docs():
    import importlib.resources

    assert (importlib.resources.files("locap") / "__init__.pyi").is_file()
    assert (importlib.resources.files("locap") / "py.typed").is_file()
    for f in (locap.read, locap.clean, locap.label, locap.solve, locap.bench_fill):
        assert f.__doc__ and len(f.__doc__) > 40, f
    assert not math.isnan(locap.read(EXAMPLE).rate_hz)
