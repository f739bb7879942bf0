"""Type stubs of the extension module ``wipdr._wipdr`` (re-exported by ``wipdr``)."""

import os
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

PathLike = Union[str, "os.PathLike[str]"]
Config = Union[None, PathLike, Mapping[str, Any]]
Bssid = Union[str, int]
ScanEntry = Union[Tuple[Bssid, float], Tuple[Bssid, float, Optional[int]]]
TimeMs = Union[int, float]
Array = npt.NDArray[np.float64]

SCHEMES: List[str]

class Walk:
    """One recorded walk: waypoints and sensor streams as float64 numpy arrays."""

    def __init__(
        self,
        id: str,
        waypoints: Optional[npt.ArrayLike] = None,
        *,
        accelerometer: Optional[npt.ArrayLike] = None,
        gyroscope: Optional[npt.ArrayLike] = None,
        magnetometer: Optional[npt.ArrayLike] = None,
        rotation_vector: Optional[npt.ArrayLike] = None,
        pressure: Optional[npt.ArrayLike] = None,
        scans: Optional[Sequence[Tuple[TimeMs, Sequence[ScanEntry]]]] = None,
        waypoint_floors: Optional[Sequence[Optional[int]]] = None,
        metadata: Optional[Mapping[str, Any]] = None,
    ) -> None: ...
    @property
    def id(self) -> str: ...
    @property
    def waypoints(self) -> Array:
        """(n, 3): t_ms, x, y."""
    @property
    def waypoint_floors(self) -> List[Optional[int]]: ...
    @property
    def accelerometer(self) -> Array:
        """(n, 4): t_ms, x, y, z (m/s²)."""
    @property
    def gyroscope(self) -> Array:
        """(n, 4): t_ms, x, y, z (rad/s)."""
    @property
    def magnetometer(self) -> Array:
        """(n, 4): t_ms, x, y, z (µT)."""
    @property
    def rotation_vector(self) -> Array:
        """(n, 4): t_ms, x, y, z of the attitude quaternion."""
    @property
    def pressure(self) -> Array:
        """(n, 2): t_ms, hPa."""
    @property
    def scans(self) -> List[Tuple[int, List[Tuple[str, float]]]]: ...
    @property
    def scans_with_times(self) -> List[Tuple[int, List[Tuple[str, float, Optional[int]]]]]: ...
    @property
    def floor(self) -> Optional[str]: ...
    @property
    def metadata(self) -> Dict[str, Any]: ...
    @property
    def duration_s(self) -> float: ...

class FloorPlan:
    """A floor plan in metres: extent, outline polygons, wall segments."""

    def __init__(
        self,
        width: float,
        height: float,
        *,
        outline: Optional[Sequence[npt.ArrayLike]] = None,
        walls: Optional[npt.ArrayLike] = None,
    ) -> None: ...
    @property
    def width(self) -> float: ...
    @property
    def height(self) -> float: ...
    @property
    def walls(self) -> Array:
        """(n, 4): x0, y0, x1, y1."""
    @property
    def outline(self) -> List[Array]: ...

class Floor:
    """A floor or building: a plan and walks (sorted by id)."""

    def __init__(
        self, walks: Sequence[Walk], plan: Optional[FloorPlan] = None, name: str = "floor"
    ) -> None: ...
    @property
    def name(self) -> str: ...
    @property
    def plan(self) -> FloorPlan: ...
    @property
    def walks(self) -> List[Walk]: ...
    @property
    def walk_ids(self) -> List[str]: ...
    def walk(self, walk_id: str) -> Walk: ...
    def folds(self) -> List[int]: ...
    @property
    def skipped_walks(self) -> List[Tuple[str, str]]: ...
    @property
    def skips(self) -> Dict[str, int]:
        """What the readers skipped when the folder was read, {kind: count} (the `skips` of
        `wipdr eval --json` for this floor; empty for a floor built from arrays)."""
    def __len__(self) -> int: ...

class SiteModel:
    """A site learned once (radio map, coverage, trails, calibrated PDR, barometric
    references, plan, settings); saved and loaded as the file ``wipdr fit`` writes."""

    @staticmethod
    def fit(
        walks: Union[Sequence[Walk], Floor],
        config: Config = None,
        floor_plan: Optional[FloorPlan] = None,
    ) -> "SiteModel": ...
    @staticmethod
    def from_walks(
        walks: Union[Sequence[Walk], Floor],
        config: Config = None,
        floor_plan: Optional[FloorPlan] = None,
    ) -> "SiteModel":
        """The former name of :meth:`fit`."""
    @staticmethod
    def from_records(
        positions: npt.ArrayLike,
        scans: Sequence[Sequence[ScanEntry]],
        config: Config = None,
    ) -> "SiteModel": ...
    @staticmethod
    def load(path: PathLike) -> "SiteModel": ...
    def save(self, path: PathLike) -> None: ...
    @property
    def name(self) -> str: ...
    @property
    def building_floors(self) -> List[int]: ...
    @property
    def provenance(self) -> Dict[str, Any]: ...
    def __len__(self) -> int: ...
    @property
    def n_aps(self) -> int: ...
    @property
    def positions(self) -> Array: ...
    @property
    def floors(self) -> List[Optional[int]]: ...


class Estimate:
    """One estimate of a Positioner."""

    @property
    def t_ms(self) -> int: ...
    @property
    def x(self) -> float: ...
    @property
    def y(self) -> float: ...
    @property
    def floor(self) -> Optional[int]: ...
    @property
    def sd_m(self) -> Optional[float]: ...
    @property
    def covariance(self) -> Optional[Tuple[Tuple[float, float], Tuple[float, float]]]: ...

class Positioner:
    """The online pipeline for one stream: raw samples in, the current estimate out."""

    def __init__(
        self,
        model: SiteModel,
        scheme: str = "ekf",
        config: Config = None,
        floor_plan: Optional[FloorPlan] = None,
        *,
        stream_id: str = "",
        start: Optional[Tuple[TimeMs, float, float]] = None,
        identity: Optional[Tuple[str, TimeMs]] = None,
    ) -> None: ...
    def push_accelerometer(self, t_ms: TimeMs, x: float, y: float, z: float) -> Optional[Estimate]: ...
    def push_gyroscope(self, t_ms: TimeMs, x: float, y: float, z: float) -> Optional[Estimate]: ...
    def push_magnetometer(self, t_ms: TimeMs, x: float, y: float, z: float) -> Optional[Estimate]: ...
    def push_rotation_vector(self, t_ms: TimeMs, x: float, y: float, z: float) -> Optional[Estimate]: ...
    def push_pressure(self, t_ms: TimeMs, hpa: float) -> Optional[Estimate]: ...
    def push_scan(self, t_ms: TimeMs, entries: Sequence[ScanEntry]) -> Optional[Estimate]: ...
    def estimate(self) -> Optional[Estimate]: ...
    def track(self) -> Array:
        """(n, 5): t_ms, x, y, floor, sd_m (NaN where unknown)."""
    def smooth(self) -> Array:
        """The stream so far smoothed offline, (n, 5) as track(); ValueError with a start."""
    def counts(self) -> Dict[str, int]: ...

def read_walk(path: PathLike) -> Walk: ...
def read_floor(dir: PathLike, cache_dir: Optional[PathLike] = None) -> Floor: ...
def evaluate(
    data: Sequence[Union[PathLike, Floor]],
    schemes: Sequence[str],
    config: Config = None,
    offline: bool = False,
) -> Dict[str, Any]: ...
def locate(
    walk: Walk,
    training: Union[Sequence[Walk], Floor],
    scheme: str,
    config: Config = None,
    floor_plan: Optional[FloorPlan] = None,
) -> Array:
    """(n, 5): t_ms, x, y, floor, sd_m (NaN where unknown)."""
