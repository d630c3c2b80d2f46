"""Type stubs of the adwi package: robot positioning-error tables from Python."""

import os
from typing import Any, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

PathLike = Union[str, os.PathLike[str]]
#: A CSV path, a pandas.DataFrame with the CSV's column names, or an (N, 6 + n) array
#: with columns x, y, z, dx, dy, dz[, j1..jn].
Samples = Union[PathLike, npt.ArrayLike, Any]
Columns = Union[None, str, Mapping[str, str]]

__all__ = [
    "AdwiError",
    "AdwiWarning",
    "BuildReport",
    "Compensation",
    "Evaluation",
    "QueryResult",
    "STATUS_NAMES",
    "RESIDUAL_NAMES",
    "EVIDENCE_NAMES",
    "COMMAND_STATUS_NAMES",
    "Table",
    "build",
    "calibrate",
    "evaluate",
]

STATUS_NAMES: Tuple[str, ...]
RESIDUAL_NAMES: Tuple[str, ...]
EVIDENCE_NAMES: Tuple[str, ...]
COMMAND_STATUS_NAMES: Tuple[str, ...]
ARRAY_COLUMNS: Tuple[str, ...]

class AdwiError(ValueError):
    """An input refused as tablec refuses it; a bad sample row's message names
    file:line:column."""

class AdwiWarning(UserWarning):
    """What tablec warns about on standard error."""

class BuildReport:
    """What build() made, as tablec build prints it."""

    output: str
    source: str
    samples: int
    repeats: Optional[Dict[str, Any]]
    spacing_mm: Optional[float]
    radius_mm: float
    radius_derived: bool
    cell_mm: float
    cell_derived: bool
    grid_dims: List[int]
    grid_origin_mm: List[float]
    grid_max_mm: List[float]
    cells: int
    covered_cells: int
    distinct_lists: int
    list_entries: int
    mean_list_len: float
    max_list_len: int
    served_cells: int
    node_sets: int
    bytes: int
    k: int
    w1: float
    w2: float
    power: float
    lambda_min: float
    zeta_min: float
    consistency_screen: bool
    joint_radius_deg: float
    served_field: str
    served_kriging: List[Dict[str, float]]
    hybrid: bool
    calibration: Optional[Dict[str, Any]]
    #: With measured_in="tracker": the rigid registration (rows, orientation, iterations,
    #: base_in_tracker, probe, residuals) and "refined", as tablec build prints them.
    registration: Optional[Dict[str, Any]]
    tuning: Optional[Dict[str, Any]]
    warnings: List[str]
    seconds: float
    def __init__(self, fields: Mapping[str, Any]) -> None: ...
    def as_dict(self) -> Dict[str, Any]: ...
    def __getitem__(self, key: str) -> Any: ...
    def keys(self) -> Iterator[str]: ...

# The keyword options below are the jobs' own (adwi_jobs' BuildArgs, EvalArgs,
# CalibrateArgs: tablec's flags of the same names); the package's tests hold these
# signatures equal to them.

def build(
    samples: Union[Samples, Sequence[Samples]],
    output: PathLike,
    *,
    columns: Columns = None,
    delimiter: Optional[str] = None,
    decimal: Optional[str] = None,
    length_unit: Optional[str] = None,
    angle_unit: Optional[str] = None,
    cell: Optional[float] = None,
    radius: Optional[float] = None,
    k: Optional[int] = None,
    w1: Optional[float] = None,
    w2: Optional[float] = None,
    power: float = 1.0,
    lambda_min: float = 0.0,
    zeta_min: float = 0.0,
    no_consistency_screen: bool = False,
    bounds: Optional[Sequence[float]] = None,
    joint_radius: Optional[float] = None,
    served_field: str = "auto",
    posture: str = "auto",
    residual_weight: str = "auto",
    merge_voxel: Optional[float] = None,
    max_table_mb: Optional[float] = None,
    robot: Optional[PathLike] = None,
    base_link: Optional[str] = None,
    tip_link: Optional[str] = None,
    flange_link: Optional[str] = None,
    hybrid: bool = False,
    compliance: bool = False,
    harmonics: int | str = "auto",
    measured_in: str = "base",
    tune: bool = False,
    tune_folds: int = 5,
    threads: Optional[int] = None,
) -> BuildReport:
    """Compile samples into a correction table at output, as tablec build."""

def evaluate(
    samples: Union[None, Samples, Sequence[Samples]] = None,
    *,
    validation: Optional[Samples] = None,
    table: Optional[PathLike] = None,
    limit: Optional[int] = None,
    folds: Optional[int] = None,
    seed: int = 0,
    by_region: bool = False,
    columns: Columns = None,
    delimiter: Optional[str] = None,
    decimal: Optional[str] = None,
    length_unit: Optional[str] = None,
    angle_unit: Optional[str] = None,
    methods: Union[None, str, Sequence[str]] = None,
    robot: Optional[PathLike] = None,
    base_link: Optional[str] = None,
    tip_link: Optional[str] = None,
    flange_link: Optional[str] = None,
    measured_in: str = "base",
    register_validation_apart: bool = False,
    rank_tol: float = 0.001,
    keep_untrustworthy: bool = False,
    compliance: bool = False,
    harmonics: int | str = "auto",
    cell: Optional[float] = None,
    radius: Optional[float] = None,
    k: Optional[int] = None,
    w1: Optional[float] = None,
    w2: Optional[float] = None,
    power: float = 1.0,
    lambda_min: float = 0.0,
    zeta_min: float = 0.0,
    no_consistency_screen: bool = False,
    bounds: Optional[Sequence[float]] = None,
    joint_radius: Optional[float] = None,
    served_field: str = "auto",
    posture: str = "auto",
    residual_weight: str = "auto",
    merge_voxel: Optional[float] = None,
    max_table_mb: Optional[float] = None,
    csv: Optional[PathLike] = None,
    json: Optional[PathLike] = None,
    report: Optional[PathLike] = None,
) -> Evaluation:
    """Compare compensation methods on held-out points, as tablec eval: one record per
    row of its --csv output; with table, score that table at the validation points."""

def calibrate(
    samples: Union[Samples, Sequence[Samples]],
    *,
    columns: Columns = None,
    delimiter: Optional[str] = None,
    decimal: Optional[str] = None,
    length_unit: Optional[str] = None,
    angle_unit: Optional[str] = None,
    robot: Optional[PathLike] = None,
    base_link: Optional[str] = None,
    tip_link: Optional[str] = None,
    flange_link: Optional[str] = None,
    output: Optional[PathLike] = None,
    urdf: Optional[PathLike] = None,
    measured_in: str = "base",
    rank_tol: float = 0.001,
    compliance: bool = False,
    harmonics: int = 0,
    true_scenario: Optional[PathLike] = None,
    true_at: Optional[PathLike] = None,
    json: Optional[PathLike] = None,
) -> Dict[str, Any]:
    """Identify the robot's kinematic deviations from samples, as tablec calibrate, and
    write the calibrated robot files."""

def plan(
    output: PathLike,
    *,
    robot: Optional[PathLike] = None,
    base_link: Optional[str] = None,
    tip_link: Optional[str] = None,
    flange_link: Optional[str] = None,
    min: Optional[Sequence[float]] = None,
    max: Optional[Sequence[float]] = None,
    box: Optional[Sequence[Sequence[float]]] = None,
    count: Optional[int] = None,
    pool: Optional[int] = None,
    seed: int = 1,
    tracker: Optional[Sequence[float]] = None,
    tracker_range: Optional[Sequence[float]] = None,
    sight_cone_deg: Optional[float] = None,
    tracker_mpe_um: Optional[Sequence[float]] = None,
    abc: Optional[Sequence[Sequence[float]]] = None,
    orientation_tolerance: float = 15.0,
    branches: str = "home",
    coverage: float = 0.3,
    criterion: str = "i",
    measured: Optional[Sequence[PathLike]] = None,
    table: Optional[PathLike] = None,
    exchange_passes: int = 2,
    rank_tol: float = 0.001,
    threads: Optional[int] = None,
) -> Dict[str, Any]:
    """Plan the poses to measure, as tablec plan, and write them to output; the dict
    carries the plan's figures and those of random poses from the same workspace
    ("planned", "random": poses, mean_variance, parameter_variance, observability)."""

def iso9283(
    measurements: Optional[PathLike] = None,
    *,
    path: Optional[PathLike] = None,
    command: Optional[PathLike] = None,
    path_plan: bool = False,
    speed: float = 100,
    cube: Optional[Sequence[float]] = None,
    abc: Sequence[float] = (0, 45, 0),
    cycles: int = 30,
    output: Optional[PathLike] = None,
    distance: Optional[Sequence[str]] = None,
    json: Optional[PathLike] = None,
    table: Optional[PathLike] = None,
    report: Optional[PathLike] = None,
) -> Dict[str, Any]:
    """ISO 9283 pose characteristics of measured cycles, as tablec iso9283; path
    characteristics of a tracker stream (path, command); or the cube's five positions, or
    its test paths (path_plan), written as a plan (cube, output)."""

class Evaluation(List[Dict[str, Any]]):
    """evaluate()'s records, with the registrations tablec eval prints for tracker-frame
    samples (None otherwise), the methods against the best, point by point, and with
    by_region=True the evaluation held out by region."""

    registration: Optional[Dict[str, Any]]
    validation_registration: Optional[Dict[str, Any]]
    comparison: Optional[Dict[str, Any]]
    by_region: Optional["Evaluation"]
    def __init__(
        self,
        records: Sequence[Dict[str, Any]] = ...,
        registration: Optional[Dict[str, Any]] = None,
        validation_registration: Optional[Dict[str, Any]] = None,
        comparison: Optional[Dict[str, Any]] = None,
        by_region: Optional["Evaluation"] = None,
    ) -> None: ...

class QueryResult:
    """Table.query's answers, one row per target."""

    error_mm: npt.NDArray[np.float64]
    orientation_rad: Optional[npt.NDArray[np.float64]]
    status_code: npt.NDArray[np.uint8]
    residual_code: npt.NDArray[np.uint8]
    evidence_code: npt.NDArray[np.uint8]
    neighbours: npt.NDArray[np.uint32]
    def __init__(self, fields: Mapping[str, Any]) -> None: ...
    @property
    def status(self) -> npt.NDArray[np.str_]: ...
    @property
    def residual(self) -> npt.NDArray[np.str_]: ...
    @property
    def evidence(self) -> npt.NDArray[np.str_]: ...
    @property
    def ok(self) -> npt.NDArray[np.bool_]: ...
    def __len__(self) -> int: ...

class Compensation(QueryResult):
    """Table.compensate's answers: the query at the targets, and the commands."""

    command_mm: npt.NDArray[np.float64]
    command_rotation_rad: Optional[npt.NDArray[np.float64]]
    command_status_code: npt.NDArray[np.uint8]
    iterations: npt.NDArray[np.uint32]
    residual_mm: npt.NDArray[np.float64]
    @property
    def command_status(self) -> npt.NDArray[np.str_]: ...

class Table:
    """A correction table, memory-mapped and validated once."""

    def __init__(self, raw: Any) -> None: ...
    @classmethod
    def open(cls, path: PathLike) -> Table: ...
    @property
    def path(self) -> str: ...
    @property
    def grid(self) -> Dict[str, Any]: ...
    @property
    def method(self) -> Dict[str, Any]: ...
    @property
    def has_orientation(self) -> bool: ...
    @property
    def has_config(self) -> bool: ...
    @property
    def is_hybrid(self) -> bool: ...
    @property
    def joint_count(self) -> Optional[int]: ...
    @property
    def joint_radius_deg(self) -> float: ...
    @property
    def has_served_field(self) -> bool: ...
    @property
    def sample_count(self) -> int: ...
    @property
    def version(self) -> int: ...
    @property
    def source_hash(self) -> int: ...
    def query(
        self,
        points: npt.ArrayLike,
        joints: Optional[npt.ArrayLike] = None,
        exact: bool = False,
        *,
        config: Optional[npt.ArrayLike] = None,
        joints_unit: str = "deg",
        tcp: Optional[Sequence[float]] = None,
    ) -> QueryResult: ...
    def compensate(
        self,
        points: npt.ArrayLike,
        joints: Optional[npt.ArrayLike] = None,
        exact: bool = False,
        *,
        config: Optional[npt.ArrayLike] = None,
        joints_unit: str = "deg",
        tolerance_mm: float = 1e-6,
        max_iterations: int = 50,
        tcp: Optional[Sequence[float]] = None,
    ) -> Compensation: ...

# Robot programs compensated offline (tablec compensate).

__all__ += ["CompensatedProgram", "compensate_program"]

class CompensatedProgram:
    output: bytes
    targets: List[Dict[str, Any]]
    summary: Dict[str, Any]
    @property
    def all_corrected(self) -> bool: ...

def compensate_program(
    table: PathLike,
    program: PathLike,
    output: Optional[PathLike] = None,
    *,
    report: Optional[PathLike] = None,
    format: Optional[str] = None,
    robot: Optional[PathLike] = None,
    base_link: Optional[str] = None,
    tip_link: Optional[str] = None,
    flange_link: Optional[str] = None,
    tool: Optional[Sequence[float]] = None,
    base: Optional[Sequence[float]] = None,
    table_tool: Optional[Sequence[float]] = None,
    max_correction_mm: float = 5.0,
    max_joint_change_deg: float = 2.0,
    strict: bool = False,
    max_seconds: float = 300.0,
    beyond_evidence: bool = False,
    krl_config: Optional[PathLike] = None,
    fanuc_uframes: Optional[Dict[int, Sequence[float]]] = None,
    fanuc_utools: Optional[Dict[int, Sequence[float]]] = None,
    fanuc_frames: Optional[PathLike] = None,
    fanuc_turn_axes: Optional[Sequence[int]] = None,
    fanuc_j23: Optional[float] = None,
    yaskawa_tools: Optional[Dict[int, Sequence[float]]] = None,
    yaskawa_users: Optional[Dict[int, Sequence[float]]] = None,
    yaskawa_pulses_per_deg: Optional[Sequence[float]] = None,
) -> CompensatedProgram: ...
