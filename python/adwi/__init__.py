"""adwi — robot positioning-error tables, from Python.

Industrial robots land 1-3 mm away from where they are told to go. From measured
samples (commanded pose, measured error) adwi compiles a memory-mapped correction table
that predicts the error at any target by approximation-degree weighted average
interpolation (Sun, Xi, Tang, 2020); the controller commands the target minus the error.

This package does what the ``tablec`` command line does, with numpy arrays:

- :func:`build` compiles samples into a table file (``tablec build``);
- :meth:`Table.open` maps a table, :meth:`Table.query` answers an (N, 3) array of targets
  and :meth:`Table.compensate` solves for the commands (``tablec query --targets``);
- :func:`evaluate` compares the methods on held-out points, or scores a table built
  before (``tablec eval``);
- :func:`calibrate` identifies the robot and writes it calibrated (``tablec calibrate``);
- :func:`plan` chooses the poses to measure (``tablec plan``), and :func:`iso9283`
  reduces measured cycles to ISO 9283 accuracy and repeatability (``tablec iso9283``).

Every function takes ``tablec``'s options of the same names as keyword arguments
(``--tune-folds`` is ``tune_folds=``), defined once for both and documented in each
function's docstring.

Samples are a CSV path, a pandas DataFrame with the CSV's column names, or a numpy array
with columns ``x, y, z, dx, dy, dz[, j1..jn]``. Positions are in mm, joint angles in
degrees (as ``tablec`` reads them), orientation errors in rad. Measurements in a laser
tracker's own frame (joints and measured poses, ``measured_in="tracker"``, as ``tablec``'s
``--measured-in tracker``) are registered to the robot first.

Every refused input raises :class:`AdwiError` (a :class:`ValueError`) with ``tablec``'s
message: a bad sample row names ``file:line:column``.
"""

from __future__ import annotations

import os
import warnings
from typing import Any, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _adwi
from ._adwi import AdwiError

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
    "iso9283",
    "plan",
]

#: Query statuses, indexed by status code: the names ``tablec query`` prints.
STATUS_NAMES: Tuple[str, ...] = tuple(_adwi.STATUS_NAMES)
#: Residual flags, indexed by code: how much of a hybrid table's residual field an
#: answer holds (``full``, ``faded``, ``model_only``), as ``tablec query`` prints them.
RESIDUAL_NAMES: Tuple[str, ...] = tuple(_adwi.RESIDUAL_NAMES)
#: Evidence flags, indexed by their bits: where an answer lies beyond what the table's
#: samples cover, as ``tablec query`` prints it.
EVIDENCE_NAMES: Tuple[str, ...] = (
    "within", "orientation", "tcp", "orientation+tcp",
    "joints", "orientation+joints", "tcp+joints", "orientation+tcp+joints",
)
#: ``command_status`` names of ``tablec query --targets``, indexed by code.
COMMAND_STATUS_NAMES: Tuple[str, ...] = tuple(_adwi.COMMAND_STATUS_NAMES)

#: The columns of a samples array, before the joints ``j1..jn``.
ARRAY_COLUMNS: Tuple[str, ...] = ("x", "y", "z", "dx", "dy", "dz")


class AdwiWarning(UserWarning):
    """What ``tablec`` warns about on standard error: a mostly empty grid, kinematic
    parameters the samples cannot identify, an identification that did not converge."""


PathLike = Union[str, "os.PathLike[str]"]
Samples = Any  # a path, a pandas.DataFrame or an (N, 6 + n) numpy array


def _is_dataframe(obj: Any) -> bool:
    return hasattr(obj, "to_csv") and hasattr(obj, "columns") and hasattr(obj, "iloc")


def _source(samples: Samples, what: str) -> Union[str, Tuple[str, bytes]]:
    """A path, or (name, CSV bytes) for a DataFrame or an array, for the native reader:
    every input goes through the one CSV reader, with its checks and messages."""
    if isinstance(samples, (str, os.PathLike)):
        return os.fspath(samples)
    if _is_dataframe(samples):
        # float repr is the shortest round-trip form: the reader gets every bit.
        text = samples.to_csv(index=False, na_rep="NaN", lineterminator="\n")
        return (f"<{what} DataFrame>", text.encode("utf-8"))
    array = np.asarray(samples, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] < len(ARRAY_COLUMNS):
        raise AdwiError(
            f"{what}: an array needs shape (N, 6 + n): columns x, y, z, dx, dy, dz and "
            f"optionally the joints j1..jn; its shape is {array.shape}"
        )
    joints = array.shape[1] - len(ARRAY_COLUMNS)
    header = list(ARRAY_COLUMNS) + [f"j{i + 1}" for i in range(joints)]
    return (f"<{what} array>", _adwi.array_csv(np.ascontiguousarray(array), header))


def _columns(columns: Union[None, str, Mapping[str, str]]) -> Optional[str]:
    if columns is None or isinstance(columns, str):
        return columns
    return ",".join(f"{name}={source}" for name, source in columns.items())


def _sources(samples: Any, what: str) -> List[Union[str, Tuple[str, bytes]]]:
    """One source, or several series (a list or tuple of them), for the native reader."""
    if isinstance(samples, (list, tuple)):
        return [_source(s, f"{what} {i + 1}") for i, s in enumerate(samples)]
    return [_source(samples, what)]


#: Options whose values are paths.
_PATH_OPTIONS = (
    "robot", "csv", "json", "report", "table", "output", "urdf", "true_scenario", "true_at",
)


def _options(files: Sequence[Any], options: Dict[str, Any]) -> Dict[str, Any]:
    """The keyword options as the job takes them: paths as strings, a column mapping dict
    as its text, bounds and method lists as lists. Their names and values are checked by
    the job, with tablec's messages."""
    given = {k: v for k, v in options.items() if v is not None}
    if any(not isinstance(f, (str, os.PathLike)) for f in files if f is not None) and (
        given.get("delimiter") or given.get("decimal")
    ):
        raise AdwiError("delimiter and decimal apply to CSV files, not to arrays or DataFrames")
    if "columns" in given:
        given["columns"] = _columns(given["columns"])
    if "bounds" in given:
        given["bounds"] = [float(v) for v in np.asarray(given["bounds"], dtype=np.float64).ravel()]
    if isinstance(given.get("methods"), str):
        given["methods"] = [m for m in given["methods"].split(",") if m]
    elif "methods" in given:
        given["methods"] = list(given["methods"])
    for name in _PATH_OPTIONS:
        if isinstance(given.get(name), os.PathLike):
            given[name] = os.fspath(given[name])
    return given


def _document(function: Any, job: str) -> Any:
    """Appends the job's options — names, defaults and help as ``tablec --help`` gives
    them, from the one definition both front ends use — to ``function``'s docstring."""
    lines = [function.__doc__ or "", "", "    Options (tablec's flags of the same names):", ""]
    for name, text, default in _adwi.options(job):
        default_text = f" [default: {default}]" if default is not None else ""
        lines.append(f"    - ``{name}``{default_text}: {' '.join(text.split())}")
    function.__doc__ = "\n".join(lines)
    return function


def _warn(messages: Sequence[str]) -> None:
    for message in messages:
        warnings.warn(message, AdwiWarning, stacklevel=3)


class BuildReport:
    """What :func:`build` made, as ``tablec build`` prints it.

    Attributes (and keys, for ``report["cells"]``): ``output``, ``source``, ``samples``,
    ``repeats`` (dict or None), ``spacing_mm``, ``radius_mm``, ``radius_derived``,
    ``cell_mm``, ``cell_derived``, ``grid_dims``, ``grid_origin_mm``, ``grid_max_mm``,
    ``cells``, ``covered_cells``, ``distinct_lists``, ``list_entries``, ``mean_list_len``,
    ``max_list_len``, ``served_cells``, ``node_sets``, ``bytes``, ``k``, ``w1``, ``w2``,
    ``power``, ``lambda_min``, ``zeta_min``, ``consistency_screen``, ``joint_radius_deg``,
    ``served_field``, ``served_kriging`` (a kriging served field's hyperparameters per
    component, x, y, z then orientation: dicts of ``length_scale_mm`` (horizontal),
    ``vertical_scale`` (vertical distances are multiplied by it), ``relative_nugget`` and
    ``modulation``, the weight of the part turning with the tool; empty for the
    method's nodes), ``hybrid``, ``calibration`` (dict or None: ``identified``,
    ``unidentifiable``, the residuals, and ``parameters``, every parameter's ``value``,
    ``standard_error`` and ``status`` as :func:`calibrate` returns them), ``registration`` (dict,
    with ``measured_in="tracker"``, or None), ``tuning`` (dict or None), ``warnings``,
    ``seconds``.

    ``registration`` is what ``tablec build --measured-in tracker`` prints: ``rows``,
    ``orientation`` (whether orientations were measured, so the probe's rotation was
    registered), ``iterations``, the transforms ``base_in_tracker`` (the robot's frame in
    the tracker's, ``p_tracker = R · p_robot + t``) and ``probe`` (the probe on the
    flange, the registered robot's tool), each a dict of ``translation_mm``,
    ``rotation_vector_deg`` (the figures tablec prints) and ``rotation`` (the 3 × 3 matrix,
    row-major); the rigid fit's ``position_rms_mm``, ``position_max_mm``,
    ``orientation_rms_rad`` and ``orientation_max_rad`` (None without orientations); and
    ``refined``: both transforms as the hybrid's identification refined them, with the
    identified model's residuals under the same names.
    """

    def __init__(self, fields: Mapping[str, Any]) -> None:
        self._fields = dict(fields)
        for name, value in self._fields.items():
            setattr(self, name, value)

    def as_dict(self) -> Dict[str, Any]:
        """The report as a plain dict."""
        return dict(self._fields)

    def __getitem__(self, key: str) -> Any:
        return self._fields[key]

    def keys(self) -> Iterator[str]:
        return iter(self._fields)

    def __repr__(self) -> str:
        f = self._fields
        return (
            f"BuildReport({f['output']!r}: {f['samples']} samples, {f['cells']} cells "
            f"({f['covered_cells']} covered), {f['bytes']} bytes)"
        )


def build(samples: Samples, output: PathLike, **options: Any) -> BuildReport:
    """Compile samples into a correction table at ``output``, as ``tablec build``.

    ``samples`` is a CSV path, a pandas DataFrame with the CSV's column names (``x, y, z,
    dx, dy, dz``, orientations, ``j1..jn``, ``config``; in a message, its line n is row
    n - 2), a numpy array with columns ``x, y, z, dx, dy, dz[, j1..jn]`` (mm, joints in
    degrees unless ``angle_unit="rad"``), or a list of them: several series in one table.
    With ``robot`` (a robot file, TOML or URDF) the table is hybrid: the robot's kinematic
    deviations are identified from the samples and the table holds the calibrated model
    and the residuals it leaves. ``columns`` may be a dict ``{"x": "x_t", ...}``.

    The table is written atomically (complete or not at all); an output that is one of
    the inputs (also through a link) is refused before anything is written. The GIL is
    released while building. Warnings are issued as :class:`AdwiWarning`. Returns the
    :class:`BuildReport`. Raises :class:`AdwiError`.
    """
    fields = _adwi.build(
        _sources(samples, "samples"),
        os.fspath(output),
        **_options([samples], options),
    )
    _warn(fields["warnings"])
    return BuildReport(fields)


def evaluate(
    samples: Optional[Samples] = None,
    *,
    validation: Optional[Samples] = None,
    **options: Any,
) -> "Evaluation":
    """Compare compensation methods on held-out points, as ``tablec eval``; or, with
    ``table``, score a table built before at the ``validation`` points (``tablec eval
    --table``).

    Either ``validation`` (samples in the same form and columns as ``samples``) or
    ``folds`` (k-fold cross-validation of ``samples``, split by ``seed``).

    Returns an :class:`Evaluation`: a list with one record per row of ``tablec eval
    --csv`` — ``uncompensated``, then one per method — with its keys: ``method``,
    ``predicted``, ``not_predicted``, ``position_{mean,rms,p95,max}_mm``,
    ``orientation_{mean,rms,p95,max}_mrad`` (None without orientations),
    ``position_mean_se_mm`` (the standard error of the position mean),
    ``position_offset_p`` (the p value of the residuals' shared offset) and ``note``;
    ``pandas.DataFrame(records)`` takes them. Its ``registration`` and
    ``validation_registration`` are the registrations ``tablec eval`` prints, or None; with
    ``folds`` and ``by_region=True``, its ``by_region`` is the evaluation held out by region
    (or by series), the second table ``tablec eval --by-region`` prints. The GIL is
    released while evaluating.
    """
    sources = [] if samples is None else _sources(samples, "samples")
    (
        records,
        messages,
        registration,
        validation_registration,
        comparison,
        by_region,
    ) = _adwi.evaluate(
        sources,
        None if validation is None else _source(validation, "validation"),
        **_options([samples, validation], options),
    )
    _warn(messages)
    return Evaluation(
        records,
        registration,
        validation_registration,
        comparison,
        None if by_region is None else Evaluation(by_region),
    )


def calibrate(samples: Samples, **options: Any) -> Dict[str, Any]:
    """Identify a robot's kinematic deviations from samples, as ``tablec calibrate``, and
    write the calibrated robot as a robot file (``output``) and as URDF (``urdf``), all
    or neither.

    Returns a dict: the keys ``tablec calibrate --json`` writes, ``robot``, ``samples``,
    ``condition_number``, ``iterations``, ``converged``, ``initial_position_rms_mm``,
    ``position_rms_mm``, ``orientation_rms_rad``, ``parameters`` (each one's ``name``,
    ``unit``, ``value``, ``held_estimate``, ``standard_error``, ``correlated_with``,
    ``correlation``, ``status``, ``reason``) and ``truth`` (with ``true_scenario`` and
    ``true_at``: the parameter error, ``length_rms_mm``, ``angle_rms_mrad`` and each
    parameter's ``identified`` and ``truth``, and the model's position error against the
    true robot, ``position_mean_mm``, ``position_rms_mm``, ``position_max_mm`` over
    ``poses``; else None); and ``identified`` (parameter: value, mm or rad),
    ``unidentifiable``, ``registration`` (tracker-frame samples), ``written`` and
    ``warnings`` (also issued as :class:`AdwiWarning`).
    """
    fields = _adwi.calibrate(_sources(samples, "samples"), **_options([samples], options))
    _warn(fields["warnings"])
    return fields


def plan(output: PathLike, **options: Any) -> Dict[str, Any]:
    """Plan the poses to measure, as ``tablec plan``: reachable candidates in the box
    (``min``, ``max``, ``box``), seen by the tracker, chosen for the identification
    (I- or D-optimality, ``criterion``) blended with coverage and improved by exchange
    passes, ordered as a short joint-space path, and written to ``output`` (CSV:
    ``j1..jn`` in degrees, the nominal ``x,y,z,a,b,c``).

    Returns a dict: ``robot``, ``joints_rad``, ``position_mm``, ``abc_deg`` (one row per
    pose, in the order to measure), ``parameters`` (the identifiable ones the selection
    weighs), ``pool``, ``draws``, ``log_det``, ``mean_variance`` (the mean prediction
    variance over the candidates, in σ², or in mm² when ``tracker_mpe_um`` weighs the
    poses) and ``variance_bound`` (no as many candidates do better),
    ``tracker_sigma_mm`` (the smallest and largest σ of a coordinate over the candidates,
    None without ``tracker_mpe_um``), ``workspace_candidates`` and ``other_branches``
    (candidates of the home branch, planned poses of another, with ``branches="all"``),
    ``min_distance_mm`` (None for a single pose), ``path_travel`` (rad) and ``written``.
    """
    return _adwi.plan(os.fspath(output), **_options([], options))


def iso9283(measurements: Optional[PathLike] = None, **options: Any) -> Dict[str, Any]:
    """ISO 9283:1998 pose characteristics of measured cycles, as ``tablec iso9283``; or,
    with ``cube=[x, y, z, side]`` and ``output``, the standard's five cube positions
    written as a plan.

    Returns a dict: ``positions`` (per position ``name``, ``n``, ``ap_p_mm``,
    ``ap_x_mm``..., ``rp_l_mm``..., the orientation figures or None), ``distance`` (between
    consecutive positions ``from``, ``to``, ``ad_p_mm``..., ``rd_mm``), ``compensated`` (the
    same for the table's compensation, with ``table``; else None) and ``written`` (with
    ``report=DIR``, the HTML page ``DIR/index.html`` among them).
    """
    files = [measurements] if measurements is not None else []
    path = os.fspath(measurements) if measurements is not None else None
    return _adwi.iso9283(path, **_options(files, options))


_document(build, "build")
_document(evaluate, "evaluate")
_document(calibrate, "calibrate")
_document(plan, "plan")
_document(iso9283, "iso9283")


class Evaluation(list):
    """The records of :func:`evaluate`: a list, one dict per row of ``tablec eval
    --csv``, with what ``tablec eval`` prints besides its table for tracker-frame samples.

    - ``registration``: the samples' registration (``measured_in="tracker"``), keys as
      :class:`BuildReport`'s ``registration``; ``refined`` is by an identification of all
      samples, as ``tablec eval`` prints it. None for base-frame samples.
    - ``validation_registration``: the validation set's own registration
      (``register_validation_apart=True``): the same keys, positions only, ``refined``
      None; otherwise None.
    - ``comparison``: every method against the best, point by point, as ``"comparison"``
      in ``tablec eval --json``: ``reference``, the method with the lowest mean of those
      that missed no point, and ``against``, one dict per other method (``method``,
      ``points`` both predicted, ``mean_difference_mm`` of its residual norm minus the
      reference's, and its ``standard_error_mm``), smallest difference first. None when no
      method has residuals.
    - ``by_region``: with ``folds`` and ``by_region=True``, the same methods held out by
      region (spatial blocks of the samples, or each series in turn), an
      :class:`Evaluation` whose records are the rows of the second table ``tablec eval
      --by-region`` prints; otherwise None.
    """

    registration: Optional[Dict[str, Any]]
    validation_registration: Optional[Dict[str, Any]]
    comparison: Optional[Dict[str, Any]]
    by_region: Optional["Evaluation"]

    def __init__(
        self,
        records: Sequence[Dict[str, Any]] = (),
        registration: Optional[Dict[str, Any]] = None,
        validation_registration: Optional[Dict[str, Any]] = None,
        comparison: Optional[Dict[str, Any]] = None,
        by_region: Optional["Evaluation"] = None,
    ) -> None:
        super().__init__(records)
        self.registration = registration
        self.validation_registration = validation_registration
        self.comparison = comparison
        self.by_region = by_region


class QueryResult:
    """The answers of :meth:`Table.query`, one row per target.

    - ``error_mm`` (N, 3): predicted position error, actual − nominal, mm; NaN where the
      status is not ``ok``.
    - ``orientation_rad`` (N, 3) or None: predicted orientation error (rotation vector,
      rad, base frame); None for a table whose samples have no orientation, a hybrid
      table's too (positions at one point do not determine its model's).
    - ``status`` (N,): status names as ``tablec query`` prints them (``ok``,
      ``outside_grid``, ``no_neighbour``, ``invalid_input``, ``missing_joints``,
      ``numerical_failure``, ``uncovered_cell``, ``joints_mismatch``: a hybrid table's
      joints do not put the tool near the target, joints given in the wrong unit, degrees
      unless ``joints_unit="rad"``); ``status_code`` the same as integers,
      indexes of :data:`STATUS_NAMES`; ``ok`` a boolean mask.
    - ``neighbours`` (N,): neighbours weighted (exact tier) or nodes blended (served tier).
    - ``residual`` (N,): how much of a hybrid table's residual field the answer holds
      (``full``, ``faded``, ``model_only``; always ``full`` for a position-only table),
      ``""`` where the status is not ``ok``; ``residual_code`` the same as integers,
      indexes of :data:`RESIDUAL_NAMES`.
    - ``evidence`` (N,): where the answer lies beyond what the table's samples cover, as
      ``tablec query`` prints it (``within``, ``orientation``: an approach axis the samples
      never had, a hybrid table's model answering alone; ``tcp``: a TCP the table cannot
      place, or whose lever its samples of position alone do not determine; ``orientation+tcp``); ``evidence_code`` the same as bits (0 within, 1
      orientation, 2 TCP).
    """

    error_mm: np.ndarray
    orientation_rad: Optional[np.ndarray]
    status_code: np.ndarray
    residual_code: np.ndarray
    evidence_code: np.ndarray
    neighbours: np.ndarray

    def __init__(self, fields: Mapping[str, Any]) -> None:
        self.error_mm = fields["error_mm"]
        self.orientation_rad = fields["orientation_rad"]
        self.status_code = fields["status_code"]
        self.residual_code = fields["residual_code"]
        self.evidence_code = fields["evidence_code"]
        self.neighbours = fields["neighbours"]

    @property
    def status(self) -> np.ndarray:
        """Status names, (N,) array of str."""
        return np.asarray(STATUS_NAMES)[self.status_code]

    @property
    def residual(self) -> np.ndarray:
        """Residual flag names, (N,) array of str (``""`` where the status is not ``ok``)."""
        names = np.asarray(RESIDUAL_NAMES + ("",))
        codes = np.where(self.residual_code == _adwi.NO_RESIDUAL, len(names) - 1,
                         self.residual_code)
        return names[codes]

    @property
    def evidence(self) -> np.ndarray:
        """Evidence flag names, (N,) array of str (``within`` where nothing is beyond)."""
        return np.asarray(EVIDENCE_NAMES)[self.evidence_code & 7]

    @property
    def ok(self) -> np.ndarray:
        """Where a correction was predicted (status ``ok``), (N,) bool."""
        return self.status_code == 0

    def __len__(self) -> int:
        return len(self.status_code)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({len(self)} targets, {int(self.ok.sum())} ok)"


class Compensation(QueryResult):
    """The answers of :meth:`Table.compensate`: those of :meth:`Table.query` at the
    targets, and the commands, as ``tablec query --targets`` writes them.

    - ``command_mm`` (N, 3): the position to command so that the robot lands on the
      target (``command + error(command) = target``, by fixed-point iteration; with
      joints, first order ``target − error``); NaN where the status is not ``ok``.
    - ``command_rotation_rad`` (N, 3) or None: the rotation vector to apply to the target
      orientation, ``R_cmd = Exp(v) · R_target``; None for position-only tables.
    - ``command_status`` (N,): ``converged``, ``not_converged``, ``first_order``, or ``""``
      where there is no command.
    - ``iterations`` (N,) and ``residual_mm`` (N,): of the fixed-point iteration
      (0 and NaN for first-order commands).
    """

    command_mm: np.ndarray
    command_rotation_rad: Optional[np.ndarray]
    command_status_code: np.ndarray
    iterations: np.ndarray
    residual_mm: np.ndarray

    def __init__(self, fields: Mapping[str, Any]) -> None:
        super().__init__(fields)
        self.command_mm = fields["command_mm"]
        self.command_rotation_rad = fields["command_rotation_rad"]
        self.command_status_code = fields["command_status_code"]
        self.iterations = fields["iterations"]
        self.residual_mm = fields["residual_mm"]

    @property
    def command_status(self) -> np.ndarray:
        """``command_status`` names, (N,) array of str (``""`` without a command)."""
        names = np.asarray(COMMAND_STATUS_NAMES + ("",))
        codes = np.where(self.command_status_code == _adwi.NO_COMMAND, len(names) - 1,
                         self.command_status_code)
        return names[codes]


def _optional_tcp(tcp: Any) -> Optional[Tuple[float, float, float]]:
    if tcp is None:
        return None
    values = np.asarray(tcp, dtype=np.float64).reshape(-1)
    if values.shape != (3,):
        raise AdwiError(f"tcp takes X, Y, Z (mm, flange frame); {values.size} values given")
    return (float(values[0]), float(values[1]), float(values[2]))


def _points(points: Any) -> np.ndarray:
    array = np.ascontiguousarray(points, dtype=np.float64)
    if array.ndim == 1:
        array = array.reshape(1, -1)
    return array


def _optional_joints(joints: Any) -> Optional[np.ndarray]:
    if joints is None:
        return None
    array = np.ascontiguousarray(joints, dtype=np.float64)
    if array.ndim == 1:
        array = array.reshape(1, -1)
    return array


def _optional_config(config: Any, n: int) -> Optional[np.ndarray]:
    if config is None:
        return None
    array = np.ascontiguousarray(config, dtype=np.int64).reshape(-1)
    if array.size == 1 and n != 1:
        array = np.full(n, array[0], dtype=np.int64)
    return array


def _joints_deg(joints_unit: str) -> bool:
    if joints_unit not in ("deg", "rad"):
        raise AdwiError(f"joints_unit: 'deg' or 'rad', not {joints_unit!r}")
    return joints_unit == "deg"


class Table:
    """A correction table, memory-mapped and validated once by :meth:`open`.

    Query it with :meth:`query` (errors) or :meth:`compensate` (commands), vectorised over
    (N, 3) arrays of targets; both release the GIL during the loop, so several threads
    can query one table at once.
    """

    def __init__(self, raw: "_adwi.Table") -> None:
        self._raw = raw

    @classmethod
    def open(cls, path: PathLike) -> "Table":
        """Map the table at ``path`` and validate it (header, checksums, structure).
        Raises :class:`AdwiError` for a file that is not a valid table."""
        return cls(_adwi.Table.open(os.fspath(path)))

    @property
    def path(self) -> str:
        """The table's file."""
        return os.fspath(self._raw.path)

    @property
    def grid(self) -> Dict[str, Any]:
        """The cell grid: ``origin_mm``, ``max_mm``, ``cell_mm``, ``dims``, ``cells``;
        targets outside it are answered ``outside_grid``."""
        return self._raw.grid

    @property
    def method(self) -> Dict[str, Any]:
        """The method's parameters: ``radius_mm``, ``k``, ``w1``, ``w2``, ``power``,
        ``lambda_min``, ``zeta_min``, ``consistency_screen``."""
        return self._raw.method

    @property
    def has_orientation(self) -> bool:
        """Whether the samples carry orientation errors, so answers include one."""
        return self._raw.has_orientation

    @property
    def has_config(self) -> bool:
        """Whether the samples carry configurations, which ``config`` then screens."""
        return self._raw.has_config

    @property
    def is_hybrid(self) -> bool:
        """Whether this is a hybrid table (calibrated model + residuals): it needs the
        targets' joint angles."""
        return self._raw.is_hybrid

    @property
    def joint_count(self) -> Optional[int]:
        """The number of joint values a query takes, or None when joints play no part."""
        return self._raw.joint_count

    @property
    def joint_radius_deg(self) -> float:
        """The joint-space screen's radius, degrees; 0 when off."""
        return self._raw.joint_radius_deg

    @property
    def has_served_field(self) -> bool:
        """Whether the table has a served (continuous) tier; otherwise every query is
        answered from the exact tier."""
        return self._raw.has_served_field

    @property
    def sample_count(self) -> int:
        """The number of samples the table was built from."""
        return self._raw.sample_count

    @property
    def version(self) -> int:
        """The file format version."""
        return self._raw.version

    @property
    def source_hash(self) -> int:
        """XXH3-64 of the sample values the table was built from."""
        return self._raw.source_hash

    def query(
        self,
        points: Any,
        joints: Any = None,
        exact: bool = False,
        *,
        config: Any = None,
        joints_unit: str = "deg",
        tcp: Any = None,
    ) -> QueryResult:
        """Predicted errors at ``points`` ((N, 3), mm, base frame; one point (3,) is one
        row), as ``tablec query --targets`` answers rows ``x,y,z[,config][,j1..jn]``.

        ``joints`` ((N, n)): the joint angles the controller will use, in degrees as tablec
        reads ``j1..jn`` (``joints_unit="rad"`` for radians); needed by hybrid tables, and
        applies a table's joint-space screen. ``config`` ((N,) ints, or one int; negative
        for unknown): the inverse-kinematics configuration. ``exact``: answer from the
        exact tier (the paper's method to the digit) instead of the served field.
        ``tcp`` (X, Y, Z mm, flange frame): the TCP the points are for, when it is not the
        point the samples measured (``tablec query --tcp``): a hybrid table answers the
        error there, its answer's rotation turning the lever (where its samples measured orientation;
        else unturned, and flagged); another flags its answers (``evidence``).
        """
        p = _points(points)
        result = self._raw.query_batch(
            p,
            joints=_optional_joints(joints),
            config=_optional_config(config, len(p)),
            exact=exact,
            compensate=False,
            joints_deg=_joints_deg(joints_unit),
            tcp=_optional_tcp(tcp),
        )
        return QueryResult(result)

    def compensate(
        self,
        points: Any,
        joints: Any = None,
        exact: bool = False,
        *,
        config: Any = None,
        joints_unit: str = "deg",
        tolerance_mm: float = _adwi.COMPENSATE_TOLERANCE_MM,
        max_iterations: int = _adwi.COMPENSATE_ITERATIONS,
        tcp: Any = None,
    ) -> Compensation:
        """The commands that land the robot on ``points``, as ``tablec query --targets``
        writes them (its ``command_*`` columns): ``command + error(command) = target`` by
        fixed-point iteration to ``tolerance_mm`` within ``max_iterations`` queries; with
        ``joints``, the first-order ``target − error`` (the moved command's joint angles
        are only known to the controller). Arguments as :meth:`query`.
        """
        p = _points(points)
        result = self._raw.query_batch(
            p,
            joints=_optional_joints(joints),
            config=_optional_config(config, len(p)),
            exact=exact,
            compensate=True,
            joints_deg=_joints_deg(joints_unit),
            tolerance_mm=tolerance_mm,
            max_iterations=max_iterations,
            tcp=_optional_tcp(tcp),
        )
        return Compensation(result)

    def __repr__(self) -> str:
        return repr(self._raw)


# ---------------------------------------------------------------------------------------
# Robot programs compensated offline (``tablec compensate``).

__all__ += ["CompensatedProgram", "compensate_program"]


class CompensatedProgram:
    """A compensated robot program: ``output``, its bytes (every target's numbers replaced,
    everything else as read); ``targets``, one dict per target as ``tablec compensate
    --report`` writes its rows (``name``, ``line``, ``column``, ``in_partner`` (True where
    the target is written in the program's partner file, a KRL ``.dat``'s ``.src``: ``line``
    and ``column`` are then the partner's), ``kind``, ``status``,
    ``detail``, ``correction_mm``, ``rotation_deg``, ``joint_change_deg``,
    ``iterations``, ``residual_mm``, ``point_mm``, ``command_mm``, ``residual`` (the
    residual flag, None where no command was computed), and ``command_joints`` in
    degrees); ``summary``, the counts (``total``, ``corrected``, ``not_corrected`` by
    status, ``residual_faded`` and ``residual_model_only`` among the corrected,
    ``largest_correction_mm``, ``largest_at``, ``text`` as tablec prints it)."""

    def __init__(self, output: bytes, targets: List[Dict[str, Any]], summary: Dict[str, Any]):
        self.output = output
        self.targets = targets
        self.summary = summary

    @property
    def all_corrected(self) -> bool:
        """Whether every target was corrected (``tablec compensate`` exits 0)."""
        return self.summary["corrected"] == self.summary["total"]

    def __repr__(self) -> str:
        return f"CompensatedProgram({self.summary['text']})"


def compensate_program(
    table: Union[str, os.PathLike],
    program: Union[str, os.PathLike],
    output: Optional[Union[str, os.PathLike]] = None,
    *,
    report: Optional[Union[str, os.PathLike]] = None,
    format: Optional[str] = None,
    robot: Optional[Union[str, os.PathLike]] = None,
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
    krl_config: Optional[Union[str, os.PathLike]] = None,
    fanuc_uframes: Optional[Dict[int, Sequence[float]]] = None,
    fanuc_utools: Optional[Dict[int, Sequence[float]]] = None,
    fanuc_frames: Optional[Union[str, os.PathLike]] = None,
    fanuc_turn_axes: Optional[Sequence[int]] = None,
    fanuc_j23: Optional[float] = None,
    yaskawa_tools: Optional[Dict[int, Sequence[float]]] = None,
    yaskawa_users: Optional[Dict[int, Sequence[float]]] = None,
    yaskawa_pulses_per_deg: Optional[Sequence[float]] = None,
) -> CompensatedProgram:
    """``tablec compensate TABLE PROGRAM -o OUTPUT``: every target of a KUKA KRL, ABB RAPID,
    URScript or CSV program replaced by the command that lands on it (docs/programs.md).

    ``output`` and ``report`` (CSV) are written atomically when given, never over an
    input. ``format``: ``"krl"``, ``"rapid"``, ``"urscript"`` or ``"csv"`` (default: by
    extension). ``robot``: a robot file, for joint targets and the posture checks
    (``base_link``, ``tip_link``, ``flange_link``: a URDF's links, as tablec's
    ``--base-link``, ``--tip-link``, ``--flange-link``). ``tool``, ``base``,
    ``table_tool``: ``[X, Y, Z, A, B, C]`` (mm, KUKA degrees), as tablec's ``--tool``,
    ``--base``, ``--table-tool``. ``strict``: raise instead of
    leaving any target unchanged. ``beyond_evidence``: correct a position-only table's
    targets at orientations its samples never had instead of refusing them (status
    ``beyond_evidence``; each target's ``evidence`` says where it lies). ``krl_config``: a
    KUKA controller's ``$config.dat``, whose ``TOOL_DATA[n]`` and ``BASE_DATA[n]`` a KRL
    program selects (tablec's ``--krl-config``). ``fanuc_uframes``, ``fanuc_utools``: a
    Fanuc program's user and tool frames by number, ``{n: [X, Y, Z, W, P, R]}`` (mm,
    degrees), and ``fanuc_frames`` the controller's ``SYSFRAME.VA`` (tablec's
    ``--fanuc-uframe``, ``--fanuc-utool``, ``--fanuc-frames``); ``fanuc_turn_axes`` the
    joints of a ``CONFIG``'s three turn numbers, ``[1, 4, 6]`` on an R-2000iB, as the
    controller's ``$SCR_GRP[1].$TURN_AXIS`` gives them (default: a frame file's holding
    it, such as ``SYMOTN.VA``, else ``[4, 5, 6]``; tablec's ``--fanuc-turn-axes``);
    ``fanuc_j23`` how the pendant counts J3 in a joint position, J3 = the robot file's J3 +
    ``fanuc_j23`` · J2 (1 where it counts J3 from the horizontal and the robot file from the
    upper arm, 0 where both count alike; without it Fanuc joint positions are refused;
    tablec's ``--fanuc-j23``). ``yaskawa_tools``,
    ``yaskawa_users``: a Yaskawa job's tool files and user frames by number, ``{n: [X, Y, Z,
    Rx, Ry, Rz]}`` (mm, degrees about the fixed x, y, z), and ``yaskawa_pulses_per_deg`` its
    axes' encoder pulses per degree (tablec's ``--yaskawa-tool``, ``--yaskawa-user``,
    ``--yaskawa-pulses-per-deg``). A malformed program raises :class:`AdwiError` naming
    ``file:line:column``.
    """
    path = lambda p: None if p is None else os.fspath(p)  # noqa: E731
    frame = lambda f: None if f is None else [float(v) for v in f]  # noqa: E731
    out, targets, summary = _adwi.compensate_program(
        os.fspath(table),
        os.fspath(program),
        output=path(output),
        report=path(report),
        format=format,
        robot=path(robot),
        base_link=base_link,
        tip_link=tip_link,
        flange_link=flange_link,
        tool=frame(tool),
        base=frame(base),
        table_tool=frame(table_tool),
        max_correction_mm=max_correction_mm,
        max_joint_change_deg=max_joint_change_deg,
        strict=strict,
        max_seconds=max_seconds,
        beyond_evidence=beyond_evidence,
        krl_config=path(krl_config),
        fanuc_uframes=None
        if fanuc_uframes is None
        else {int(n): frame(f) for n, f in fanuc_uframes.items()},
        fanuc_utools=None
        if fanuc_utools is None
        else {int(n): frame(f) for n, f in fanuc_utools.items()},
        fanuc_frames=path(fanuc_frames),
        fanuc_turn_axes=None
        if fanuc_turn_axes is None
        else [int(j) for j in fanuc_turn_axes],
        fanuc_j23=None if fanuc_j23 is None else float(fanuc_j23),
        yaskawa_tools=None
        if yaskawa_tools is None
        else {int(n): frame(f) for n, f in yaskawa_tools.items()},
        yaskawa_users=None
        if yaskawa_users is None
        else {int(n): frame(f) for n, f in yaskawa_users.items()},
        yaskawa_pulses_per_deg=frame(yaskawa_pulses_per_deg),
    )
    return CompensatedProgram(bytes(out), targets, summary)
