"""measured_in="tracker": the shipped UR10 laser-tracker measurements through adwi as
`tablec ... --measured-in tracker` reads them: the same table bytes, the same figures and
the same registration, and the same refusals."""

import json
import math
import subprocess

import numpy as np
import pytest

import adwi
from conftest import KR150, UR10, UR10_B, UR10_C, UR10_TRACKER_COLUMNS, read_frame

ROBOT = UR10 / "robot.toml"
# Coarser cells than the derived 10 mm: the same comparison at a fifth of the table size.
CELL = 30


def run_tablec(tablec, *args):
    """tablec's standard output; it must succeed."""
    done = subprocess.run(
        [str(tablec), *map(str, args)], check=True, capture_output=True, text=True
    )
    return done.stdout


def block(stdout, first):
    """The line of `stdout` that starts with `first`, and the three after it."""
    lines = stdout.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(first))
    return lines[start : start + 4]


# The lines tablec prints for a registration (compiler/tablec/src/measured_in.rs), made
# from the dicts adwi returns: equal lines mean equal figures to every digit printed.


def transform_line(name, t):
    p, r = t["translation_mm"], t["rotation_vector_deg"]
    angle = math.sqrt(sum(v * v for v in r))
    return (
        f"  {name}  translation ({p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f}) mm, rotation vector "
        f"({r[0]:.5f}, {r[1]:.5f}, {r[2]:.5f})° ({angle:.5f}°)"
    )


def residual_line(name, fit):
    line = (
        f"  {name:<15}  position RMS {fit['position_rms_mm']:.4f} mm, "
        f"max {fit['position_max_mm']:.4f} mm"
    )
    if fit["orientation_rms_rad"] is not None:
        line += (
            f"; orientation RMS {fit['orientation_rms_rad'] * 1e3:.4f} mrad, "
            f"max {fit['orientation_max_rad'] * 1e3:.4f} mrad"
        )
    return line


def transform_lines(fit):
    return [
        transform_line("base in tracker", fit["base_in_tracker"]),
        transform_line("probe on flange", fit["probe"]),
    ]


def registration_block(r):
    measured = (
        "6-D (positions and orientations)"
        if r["orientation"]
        else "positions only (probe rotation kept from the robot file)"
    )
    header = (
        f"registration   {r['rows']} rows in the tracker frame, {measured}, rigid fit of the "
        f"nominal robot ({r['iterations']} iterations)"
    )
    return [header, *transform_lines(r), residual_line("fit residuals", r)]


def refined_block(refined):
    header = "refined        by the identification's base and tool parameters:"
    return [header, *transform_lines(refined), residual_line("residuals", refined)]


def validation_block(r):
    header = (
        f"validation     registered apart ({r['rows']} rows): the robot's frame in the moved "
        "tracker's, fitted to the calibrated model's TCP positions; the probe is the samples'"
    )
    return [header, *transform_lines(r), residual_line("fit residuals", r)]


def test_tracker_hybrid_table_is_byte_identical_to_tablec(tablec, tmp_path):
    # The registration is the subject: the served field, the posture term and the joint-space
    # terms are given, not chosen by cross-validating the whole build (test_build.py checks
    # the choice).
    options = dict(
        columns=UR10_TRACKER_COLUMNS, robot=ROBOT, cell=CELL, served_field="method", posture="off",
        harmonics=0,
    )
    ours = tmp_path / "ours.tbl"
    report = adwi.build(UR10_C, ours, measured_in="tracker", **options)
    theirs = tmp_path / "tablec.tbl"
    stdout = run_tablec(
        tablec, "build", UR10_C, "-o", theirs, "--columns", UR10_TRACKER_COLUMNS,
        "--robot", ROBOT, "--measured-in", "tracker", "--cell", CELL,
        "--served-field", "method", "--posture", "off", "--harmonics", "0",
    )
    assert ours.read_bytes() == theirs.read_bytes()
    r = report.registration
    assert (r["rows"], r["orientation"], report.samples) == (2773, True, 2773)
    assert block(stdout, "registration ") == registration_block(r)
    assert block(stdout, "refined ") == refined_block(r["refined"])
    # The T-Mac probe, 92.82 mm along the flange's z axis and turned -90° about it
    # (docs/tracker.md); the matrix is the rotation the rotation vector gives.
    assert r["probe"]["translation_mm"][2] == pytest.approx(92.8241, abs=5e-5)
    assert r["probe"]["rotation_vector_deg"][2] == pytest.approx(-89.9977, abs=5e-5)
    rotation = np.array(r["probe"]["rotation"])
    assert rotation[:2, :2] == pytest.approx(np.array([[0, 1], [-1, 0]]), abs=3e-3)
    assert rotation @ rotation.T == pytest.approx(np.eye(3), abs=1e-12)
    # The same measurements as a DataFrame go through the same reader and registration.
    frame = read_frame(UR10_C, sep=";", decimal=",")
    from_frame = tmp_path / "frame.tbl"
    again = adwi.build(frame, from_frame, measured_in="tracker", **options)
    assert from_frame.read_bytes() == theirs.read_bytes()
    assert again.registration == r


def tablec_eval_json(tablec, tmp_path, *args):
    """tablec eval's standard output (the registrations) and its --json evaluation."""
    out = tmp_path / "evaluation.json"
    stdout = run_tablec(tablec, "eval", *args, "--json", out)
    return stdout, json.loads(out.read_text())


def assert_same_figures(records, evaluation):
    """The records equal tablec's JSON figures exactly (both are the f64s computed)."""
    expected = [
        (
            "uncompensated",
            evaluation["uncompensated_position_mm"],
            evaluation["uncompensated_orientation_mrad"],
            0,
        )
    ] + [
        (m["method"], m["position_mm"], m["orientation_mrad"], sum(m["not_predicted"].values()))
        for m in evaluation["methods"]
    ]
    assert [r["method"] for r in records] == [e[0] for e in expected]
    for record, (method, position, orientation, missed) in zip(records, expected):
        assert (record["predicted"], record["not_predicted"]) == (position["count"], missed)
        figures = (("position", "mm", position), ("orientation", "mrad", orientation))
        for prefix, unit, stats in figures:
            for name in ("mean", "rms", "p95", "max"):
                key = f"{prefix}_{name}_{unit}"
                assert record[key] == stats[f"{name}_norm"], (method, key)


# The evaluations below check the registrations: they identify no joint-space terms,
# whose choice would identify every block's model once per count (test_evaluate.py checks
# the default against tablec's).
def tracker_eval_args(*extra):
    return [
        UR10_C, "--validation", UR10_B, "--limit", "200", "--columns", UR10_TRACKER_COLUMNS,
        "--robot", ROBOT, "--measured-in", "tracker", "--harmonics", "0", *extra,
    ]


def test_tracker_evaluation_equals_tablec(tablec, tmp_path):
    # Series B through series C's registration: one tracker position, one probe.
    records = adwi.evaluate(
        UR10_C, validation=UR10_B, limit=200, columns=UR10_TRACKER_COLUMNS, robot=ROBOT,
        measured_in="tracker", methods="paper,kinematic,hybrid", harmonics=0,
    )
    stdout, evaluation = tablec_eval_json(
        tablec, tmp_path, *tracker_eval_args("--methods", "paper,kinematic,hybrid")
    )
    assert_same_figures(records, evaluation)
    assert [r["method"] for r in records] == ["uncompensated", "paper", "kinematic", "hybrid"]
    assert isinstance(records, list)
    assert block(stdout, "registration ") == registration_block(records.registration)
    assert block(stdout, "refined ") == refined_block(records.registration["refined"])
    assert records.validation_registration is None


def test_tracker_validation_registered_apart_equals_tablec(tablec, tmp_path):
    records = adwi.evaluate(
        UR10_C, validation=UR10_B, limit=200, columns=UR10_TRACKER_COLUMNS, robot=ROBOT,
        measured_in="tracker", register_validation_apart=True, methods=["kinematic"],
        harmonics=0,
    )
    stdout, evaluation = tablec_eval_json(
        tablec, tmp_path,
        *tracker_eval_args("--register-validation-apart", "--methods", "kinematic"),
    )
    assert_same_figures(records, evaluation)
    v = records.validation_registration
    # Registered on all 1495 rows of series B, before the limit; positions only.
    assert (v["rows"], v["orientation_rms_rad"], v["refined"]) == (1495, None, None)
    assert block(stdout, "validation ") == validation_block(v)
    assert block(stdout, "registration ") == registration_block(records.registration)
    # The probe is the samples'.
    assert v["probe"] == records.registration["probe"]


def test_measured_in_is_base_or_tracker(tmp_path):
    out = tmp_path / "t.tbl"
    with pytest.raises(ValueError, match="measured_in: unknown variant `robot`, expected `base` or `tracker`"):
        adwi.build(KR150 / "samples.csv", out, measured_in="robot")
    with pytest.raises(adwi.AdwiError, match="measured_in: unknown variant `Tracker`, expected `base` or `tracker`"):
        adwi.evaluate(KR150 / "samples.csv", folds=3, measured_in="Tracker")
    assert not out.exists()
    # "base", the default, reads the samples as they are: nothing registered.
    assert adwi.build(KR150 / "samples.csv", out, measured_in="base").registration is None
    base = adwi.evaluate(KR150 / "samples.csv", folds=3, methods="paper")
    assert (base.registration, base.validation_registration) == (None, None)
    assert base == adwi.evaluate(KR150 / "samples.csv", folds=3, methods="paper", measured_in="base")


def test_tracker_frame_refusals(tmp_path):
    out = tmp_path / "t.tbl"
    tracker = dict(columns=UR10_TRACKER_COLUMNS, measured_in="tracker")
    # As tablec: --measured-in tracker requires --robot (the same job checks both), named
    # as Python names them.
    with pytest.raises(adwi.AdwiError, match=r"^measured_in tracker needs the robot file .*\(robot\)"):
        adwi.build(UR10_C, out, **tracker)
    with pytest.raises(adwi.AdwiError, match=r"^measured_in tracker needs the robot file"):
        adwi.evaluate(UR10_C, folds=3, **tracker)
    # --register-validation-apart requires --validation and a tracker frame.
    with pytest.raises(adwi.AdwiError, match=r"^register_validation_apart needs a validation set"):
        adwi.evaluate(UR10_C, folds=3, robot=ROBOT, register_validation_apart=True, **tracker)
    with pytest.raises(adwi.AdwiError, match=r"^register_validation_apart needs measured_in tracker"):
        adwi.evaluate(
            KR150 / "samples.csv", validation=KR150 / "validation.csv",
            register_validation_apart=True,
        )
    # Too few rows to register, named as the reader names a DataFrame.
    frame = read_frame(UR10_C, sep=";", decimal=",").head(3)
    with pytest.raises(
        adwi.AdwiError,
        match=r"^cannot register <samples DataFrame>: 3 measured positions cannot register",
    ):
        adwi.build(frame, out, robot=ROBOT, **tracker)
    assert not out.exists()
