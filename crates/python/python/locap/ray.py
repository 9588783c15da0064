"""Many takes on a Ray cluster: one take per Ray task.

``locap.ray.clean(paths_or_folders, out_dir)`` (and :func:`solve`, :func:`label`) finds the
takes the way the CLI does (folders searched recursively, links to folders not followed, a
file reached twice read once), sends one task per take to the cluster, and writes each result
atomically to the name the CLI would give it (``locap clean FOLDER -o OUT_DIR``: the take's
path relative to the folder all inputs share, under ``out_dir``, which is always a folder, even
for a single take). A take that fails is one
row of the summary with the CLI's message (``path: reason``); the others go on.

Every task reads and writes through the paths it is given, so on a multi-machine cluster the
inputs and ``out_dir`` must be on a filesystem every worker mounts at the same path (NFS, a
parallel filesystem). Connect to a running cluster with ``RAY_ADDRESS`` (or ``address=``);
without one, Ray starts a local cluster on this machine. See docs/python.md.
"""

from __future__ import annotations

import os
import time
from pathlib import Path, PurePath
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple, Union

import locap

try:
    import ray as _ray
except ImportError as _missing:  # pragma: no cover - depends on the environment
    raise ImportError("locap.ray needs Ray: pip install 'ray>=2.9' (or pip install './crates/python[ray]')") from _missing

PathLike = Union[str, "os.PathLike[str]"]

__all__ = ["clean", "solve", "label", "expand", "output_paths"]


def _cannot_open(path: str, err: OSError, what: str = "cannot open") -> str:
    # Worded as the CLI words an io::Error: "path: cannot open: No such file or directory (os error 2)".
    return f"{path}: {what}: {os.strerror(err.errno or 0)} (os error {err.errno})"


def _has_extension(name: str, extensions: Sequence[str]) -> bool:
    suffix = PurePath(name).suffix
    return bool(suffix) and suffix[1:].lower() in {e.lower() for e in extensions}


def _walk(folder: str, extensions: Sequence[str], out: List[str], failures: List[str]) -> None:
    try:
        entries = list(os.scandir(folder))
    except OSError as err:
        failures.append(_cannot_open(folder, err, "cannot list folder"))
        return
    for entry in entries:
        # Links to folders are never entered (a link loop, or `up -> ..`, would walk forever).
        if entry.is_dir(follow_symlinks=False):
            _walk(entry.path, extensions, out, failures)
        elif _has_extension(entry.name, extensions):
            try:
                st = os.stat(entry.path)
            except OSError as err:
                failures.append(_cannot_open(entry.path, err))
                continue
            if _is_file(st):
                out.append(entry.path)
            elif not _is_dir(st):
                failures.append(f"{entry.path}: not a regular file (a pipe or device?); not read")


def _is_file(st: os.stat_result) -> bool:
    import stat

    return stat.S_ISREG(st.st_mode)


def _is_dir(st: os.stat_result) -> bool:
    import stat

    return stat.S_ISDIR(st.st_mode)


def expand(paths: Iterable[PathLike], extensions: Sequence[str]) -> Tuple[List[str], List[str]]:
    """The takes named by ``paths`` as the CLI finds them, and the ``path: reason`` of every
    path that could not be read.

    Files are kept as given; folders are searched recursively for files whose extension
    (case-insensitive) is one of ``extensions``, sorted within each folder; the same file
    reached twice (two spellings, a link) is kept once.
    """
    files: List[str] = []
    failures: List[str] = []
    for given in paths:
        path = os.fspath(given)
        try:
            st = os.stat(path)
        except OSError as err:
            failures.append(_cannot_open(path, err))
            continue
        if _is_dir(st):
            found: List[str] = []
            _walk(path, extensions, found, failures)
            # Component-wise, as Rust sorts paths.
            files.extend(sorted(found, key=lambda p: PurePath(p).parts))
        elif _is_file(st):
            files.append(path)
        else:
            failures.append(f"{path}: not a regular file (a pipe or device?); not read")
    seen = set()
    unique = []
    for f in files:
        try:
            st = os.stat(f)
            key = (st.st_dev, st.st_ino)
        except OSError:
            key = None
        if key is None or key not in seen:
            seen.add(key)
            unique.append(f)
    return unique, failures


def output_paths(files: Sequence[str], out_dir: PathLike, extension: Optional[str] = None) -> List[str]:
    """Where each of ``files`` goes under ``out_dir``, as the CLI names batch outputs: its
    path relative to the folder all inputs share (so takes of the same name in different
    folders never overwrite each other), with ``extension`` in place of its own when given."""
    parents = [PurePath(f).parent for f in files]
    common = parents[0] if parents else PurePath("")
    for p in parents[1:]:
        while p.parts[: len(common.parts)] != common.parts:
            if common.parts == ():
                break
            common = common.parent if common.parent != common else PurePath("")
    out = []
    for f in files:
        pf = PurePath(f)
        if pf.parts[: len(common.parts)] == common.parts:
            relative = PurePath(*pf.parts[len(common.parts) :])
        else:
            relative = PurePath(pf.name)
        target = PurePath(os.fspath(out_dir)) / relative
        if extension is not None:
            target = target.with_suffix("." + extension)
        out.append(str(target))
    return out


def _check_outputs(inputs: Sequence[str], targets: Sequence[str]) -> None:
    # As the CLI: refuse, before any work, a run whose output is one of its inputs or whose
    # outputs collide.
    ids = {}
    for f in inputs:
        try:
            st = os.stat(f)
            ids[(st.st_dev, st.st_ino)] = f
        except OSError:
            pass
    seen: Dict[str, str] = {}
    for t in targets:
        try:
            st = os.stat(t)
            if (st.st_dev, st.st_ino) in ids:
                raise ValueError(f"{t}: this output is the input {ids[(st.st_dev, st.st_ino)]}; locap never overwrites its input")
        except FileNotFoundError:
            pass
        key = os.path.abspath(t)
        if key in seen:
            raise ValueError(f"{seen[key]} and {t} would be written to the same file; nothing was done")
        seen[key] = t


def _failed(path: str, error: str) -> Dict[str, Any]:
    return {"input": path, "output": None, "ok": False, "error": error, "seconds": 0.0}


def _run_one(kind: str, src: str, dst: str, options: Dict[str, Any], extra: Optional[str]) -> Dict[str, Any]:
    """One take, in a Ray worker: read, run the stage, write; a failure is a row, not an
    exception, so the batch goes on."""
    started = time.perf_counter()
    row: Dict[str, Any] = {"input": src, "output": dst, "ok": True, "error": None}
    try:
        parent = os.path.dirname(dst)
        if parent:
            try:
                os.makedirs(parent, exist_ok=True)
            except OSError as err:
                raise locap.Error(_cannot_open(parent, err, "cannot create folder")) from err
        take = locap.read(src)
        if kind == "clean":
            result = locap.clean(take, **options)
            result.write(dst)
            report = result.report
        elif kind == "solve":
            motion = locap.solve(take, **options)
            motion.write_bvh(dst)
            if extra is not None:
                markers_parent = os.path.dirname(extra)
                if markers_parent:
                    os.makedirs(markers_parent, exist_ok=True)
                motion.cleaned.write(extra)
                row["markers_output"] = extra
            report = dict(motion.cleaned.report, frames=motion.frame_count, rate_hz=motion.rate_hz)
        else:
            template = options.pop("template")
            result = locap.label(take, template, **options)
            result.write(dst)
            report = result.report
        row.update({k: v for k, v in report.items() if not isinstance(v, (list, dict))})
    except locap.Error as err:
        row.update(output=None, ok=False, error=str(err))
    except Exception as err:  # noqa: BLE001 - any failure of one take is that take's row
        row.update(output=None, ok=False, error=f"{src}: {err}")
    row["seconds"] = time.perf_counter() - started
    return row


def _fan_out(
    kind: str,
    paths_or_folders: Union[PathLike, Iterable[PathLike]],
    out_dir: PathLike,
    extensions: Sequence[str],
    out_extension: Optional[str],
    options: Dict[str, Any],
    markers_dir: Optional[PathLike] = None,
    address: Optional[str] = None,
    num_cpus: float = 1,
) -> List[Dict[str, Any]]:
    if isinstance(paths_or_folders, (str, os.PathLike)):
        paths_or_folders = [paths_or_folders]
    files, failures = expand(paths_or_folders, extensions)
    if not files:
        if failures:
            raise locap.Error("no input could be read: " + "; ".join(failures))
        raise locap.Error(f"no input files found (looked for {', '.join(extensions)} files)")
    targets = output_paths(files, out_dir, out_extension)
    marker_targets = output_paths(files, markers_dir, "c3d") if markers_dir is not None else [None] * len(files)
    _check_outputs(files, targets + [t for t in marker_targets if t is not None])
    os.makedirs(os.fspath(out_dir), exist_ok=True)
    if not _ray.is_initialized():
        # address None: RAY_ADDRESS if set, else a local cluster on this machine.
        _ray.init(address=address)
    task = _ray.remote(num_cpus=num_cpus)(_run_one)
    refs = [task.remote(kind, src, dst, dict(options), extra) for src, dst, extra in zip(files, targets, marker_targets)]
    rows = [_failed(f.split(": ", 1)[0], f) for f in failures]
    for src, ref in zip(files, refs):
        try:
            rows.append(_ray.get(ref))
        except _ray.exceptions.RayError as err:
            # The worker itself died (out of memory, killed): this take failed, the rest go on.
            rows.append(_failed(src, f"{src}: {err}"))
    return rows


def clean(
    paths_or_folders: Union[PathLike, Iterable[PathLike]],
    out_dir: PathLike,
    *,
    address: Optional[str] = None,
    num_cpus: float = 1,
    **options: Any,
) -> List[Dict[str, Any]]:
    """``locap clean PATHS... -o OUT_DIR`` on a Ray cluster, one C3D take per task.

    ``options`` are :func:`locap.clean`'s (``method``, ``neighbours``, ``outliers``, ...).
    Returns one dict per take (paths that could not be read first): ``input``, ``output``,
    ``ok``, ``error`` (``path: reason``), ``seconds`` and the cleaning summary (``gaps``,
    ``filled_samples``, ``still_missing``, ``outliers``, ``swaps``, ...).
    """
    return _fan_out("clean", paths_or_folders, out_dir, ("c3d",), None, options, address=address, num_cpus=num_cpus)


def solve(
    paths_or_folders: Union[PathLike, Iterable[PathLike]],
    out_dir: PathLike,
    *,
    markers_out: Optional[PathLike] = None,
    address: Optional[str] = None,
    num_cpus: float = 1,
    **options: Any,
) -> List[Dict[str, Any]]:
    """``locap solve PATHS... -o OUT_DIR [--markers-out DIR]`` on a Ray cluster: one C3D or
    TRC take per task, BVH out. ``options`` are :func:`locap.solve`'s (``model``,
    ``fill``, ``refiner``, ``method``, ``layout``)."""
    return _fan_out(
        "solve", paths_or_folders, out_dir, ("c3d", "trc"), "bvh", options, markers_out, address, num_cpus
    )


def label(
    paths_or_folders: Union[PathLike, Iterable[PathLike]],
    out_dir: PathLike,
    *,
    template: PathLike,
    address: Optional[str] = None,
    num_cpus: float = 1,
    **options: Any,
) -> List[Dict[str, Any]]:
    """``locap label RAW... --template T -o OUT_DIR`` on a Ray cluster, one raw C3D take per
    task. ``options`` are :func:`locap.label`'s (``template_frame``, ``keep_unlabeled``,
    ``method``, ...)."""
    options = dict(options, template=os.fspath(template))
    return _fan_out("label", paths_or_folders, out_dir, ("c3d",), None, options, address=address, num_cpus=num_cpus)
