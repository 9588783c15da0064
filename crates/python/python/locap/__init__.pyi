"""Type stubs of locap (the native module locap._locap, re-exported)."""

import os
from typing import Any, Dict, List, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt


_Path = Union[str, "os.PathLike[str]"]

__version__: str

class Error(Exception):
    """A take or file locap could not process; ``str(err)`` is the CLI's ``path: reason``."""

class Take:
    """A marker take: positions in millimetres, NaN where a marker is missing."""

    def __init__(
        self,
        positions: npt.NDArray[np.float64],
        labels: Sequence[str],
        rate_hz: float,
        first_frame: int = 1,
        up_axis: str = "Z",
    ) -> None:
        """A take from positions (frames x markers x 3, mm, NaN = missing), one label per marker."""
    @property
    def positions(self) -> npt.NDArray[np.float64]:
        """Frames x markers x 3, millimetres, NaN where missing (a copy)."""
    @positions.setter
    def positions(self, value: npt.NDArray[np.float64]) -> None: ...
    @property
    def residuals_mm(self) -> npt.NDArray[np.float64]:
        """Frames x markers, mm; 0 for samples locap computed, NaN where missing."""
    @property
    def filled(self) -> npt.NDArray[np.bool_]:
        """Frames x markers, True where locap computed the sample (LOCAP:FILLED)."""
    @property
    def labels(self) -> List[str]:
        """Marker names (``Subject:LABEL`` where the file has a prefix)."""
    @property
    def rate_hz(self) -> float: ...
    @property
    def first_frame(self) -> int: ...
    @property
    def up_axis(self) -> str:
        """``"Y"`` or ``"Z"``."""
    @property
    def frame_count(self) -> int: ...
    @property
    def marker_count(self) -> int: ...
    @property
    def path(self) -> Optional[str]:
        """The file it was read from."""
    @property
    def warnings(self) -> List[str]:
        """What the reader noticed but read past."""
    @property
    def report(self) -> Optional[Dict[str, Any]]:
        """The stage's summary (cleaning: gaps, filled_samples, still_missing, outliers, swaps, markers)."""
    @property
    def parameters(self) -> Dict[str, Dict[str, Any]]:
        """C3D parameters, ``{"GROUP": {"NAME": value}}``; empty for TRC/CSV."""
    def write(self, path: _Path, *, trc_unit: str = "mm") -> None:
        """Writes C3D, TRC or CSV by extension, atomically; C3D keeps the input's parameters and analog data."""

class Motion:
    """Skeleton motion solved from markers (Y-up, millimetres)."""

    @property
    def joint_names(self) -> List[str]: ...
    @property
    def parents(self) -> List[int]:
        """Parent index per joint, -1 for the root."""
    @property
    def end_sites(self) -> List[bool]: ...
    @property
    def offsets_mm(self) -> npt.NDArray[np.float64]:
        """Joints x 3 bone offsets, mm."""
    @property
    def rotations(self) -> npt.NDArray[np.float64]:
        """Frames x joints x 4 local unit quaternions (w, x, y, z)."""
    @property
    def root_translation_mm(self) -> npt.NDArray[np.float64]:
        """Frames x 3 root positions, mm."""
    def global_positions_mm(self) -> npt.NDArray[np.float64]:
        """Frames x joints x 3 global joint positions, mm (forward kinematics)."""
    @property
    def rate_hz(self) -> float: ...
    @property
    def frame_count(self) -> int: ...
    @property
    def cleaned(self) -> Take:
        """The cleaned markers the motion was solved from."""
    def write_bvh(self, path: _Path, *, unit: str = "cm") -> None:
        """Writes BVH (cm by default, as ``locap solve``), atomically."""

def read(path: _Path) -> Take:
    """A take from a C3D, TRC or CSV file; raises :class:`Error` (``path: reason``)."""

def clean(
    take: Take,
    *,
    method: str = "auto",
    models: Sequence[_Path] = ...,
    neighbours: int = 6,
    ranking: str = "variance",
    outliers: bool = True,
    body_threshold_m_s2: float = ...,
    hand_threshold_m_s2: float = ...,
) -> Take:
    """``locap clean``: swaps undone, outliers removed and refilled, gaps filled.

    ``method``: edm, linear, spline, pca, pca-aligned, rigid, rigid-spline, auto or neural (``models``: refiner files).
    """

def label(
    raw: Take,
    template: Union[Take, _Path],
    *,
    template_frame: Optional[int] = None,
    fit_distance_mm: float = 60.0,
    keep_unlabeled: bool = False,
    method: str = "ours",
) -> Take:
    """``locap label``: names the points of ``raw`` online from a labeled template take."""

def solve(
    take: Take,
    *,
    model: Optional[_Path] = None,
    fill: str = "auto",
    refiner: Optional[_Path] = None,
    method: str = "auto",
    layout: Optional[_Path] = None,
) -> Motion:
    """``locap solve``: cleaning (``fill`` as ``clean``'s ``method``; a refiner only with
    ``fill="neural"`` or ``refiner=``), then the motion solver (built-in CMU 41-marker by
    default). ``method`` as ``locap solve --method``: ``auto`` (the network refined by the
    kinematic solver where the network's markers are all in the take, else the kinematic
    solver alone), ``network`` (the network alone, about 30 times faster), ``ik`` (the kinematic solver on
    ``layout``, a layout with a skeleton section; default the CMU 41-marker layout) or
    ``refine`` (the network's answer refined by the kinematic solver). The motion is in the
    animation tools' Y-up frame, as ``locap solve`` writes it."""

def bench_fill(
    takes: Sequence[Union[Take, _Path]],
    *,
    gaps: str = "real",
    gap_source: Sequence[_Path] = ...,
    max_gap: int = 600,
    uniform_fraction: float = 0.1,
    seed: int = 1,
    neighbours: int = 6,
    models: Sequence[_Path] = ...,
    no_neural: bool = False,
) -> Dict[str, Any]:
    """``locap bench fill``: the report (``--json``) as a dict, the printed table under ``"table"``."""
