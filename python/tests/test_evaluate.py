"""adwi.evaluate: the figures of `tablec eval --csv`, as records pandas takes."""

import csv
import json
import subprocess

import pandas as pd
import pytest

import adwi
from conftest import KR150, UR5, UR5_COLUMNS, UR5_GRID, UR5_RANDOM, read_frame

FIGURES = [
    "position_mean_mm",
    "position_rms_mm",
    "position_p95_mm",
    "position_max_mm",
    "orientation_mean_mrad",
    "orientation_rms_mrad",
    "orientation_p95_mrad",
    "orientation_max_mrad",
    "position_mean_se_mm",
]


def tablec_eval(tablec, tmp_path, *args):
    out = tmp_path / "figures.csv"
    subprocess.run(
        [str(tablec), "eval", *map(str, args), "--quiet", "--csv", str(out)],
        check=True,
        capture_output=True,
    )
    with open(out, newline="") as f:
        return list(csv.DictReader(f))


def assert_same_figures(records, rows):
    assert [r["method"] for r in records] == [r["method"] for r in rows]
    for record, row in zip(records, rows):
        assert set(record) == set(row)
        assert record["predicted"] == int(row["predicted"])
        assert record["not_predicted"] == int(row["not_predicted"])
        assert record["note"] == row["note"]
        for key in FIGURES:
            if row[key] == "":
                assert record[key] is None
            else:
                assert format(record[key], ".9f") == row[key], (record["method"], key)
        if row["position_offset_p"] == "":
            assert record["position_offset_p"] is None
        else:
            assert float(row["position_offset_p"]) == pytest.approx(
                record["position_offset_p"], rel=5e-4
            )


def test_kr150_validation_equals_tablec(tablec, tmp_path):
    records = adwi.evaluate(
        KR150 / "samples.csv",
        validation=KR150 / "validation.csv",
        limit=70,
        methods=["paper", "paper-trilinear", "idw", "grid"],
    )
    rows = tablec_eval(
        tablec, tmp_path, KR150 / "samples.csv", "--validation", KR150 / "validation.csv",
        "--limit", "70", "--methods", "paper,paper-trilinear,idw,grid",
    )
    assert_same_figures(records, rows)
    frame = pd.DataFrame(records).set_index("method")
    # README, "Accuracy": the first 70 validation poses.
    assert frame.loc["uncompensated", "position_mean_mm"] == pytest.approx(1.8918, abs=5e-5)
    assert frame.loc["paper", "position_mean_mm"] == pytest.approx(0.0577, abs=5e-5)
    assert frame.loc["paper", "position_max_mm"] == pytest.approx(0.1205, abs=5e-5)


def test_ur5_with_robot_equals_tablec(tablec, tmp_path):
    records = adwi.evaluate(
        UR5_GRID,
        validation=UR5_RANDOM,
        columns=UR5_COLUMNS,
        robot=UR5 / "robot.toml",
        cell=30,
        methods="paper,kinematic,hybrid",
    )
    rows = tablec_eval(
        tablec, tmp_path, UR5_GRID, "--validation", UR5_RANDOM, "--columns", UR5_COLUMNS,
        "--robot", UR5 / "robot.toml", "--cell", "30", "--methods", "paper,kinematic,hybrid",
    )
    assert_same_figures(records, rows)
    by_method = {r["method"]: r for r in records}
    # README, "Accuracy": real UR5 data.
    assert by_method["paper"]["position_mean_mm"] == pytest.approx(0.5221, abs=5e-5)
    assert by_method["hybrid"]["position_mean_mm"] == pytest.approx(0.0853, abs=5e-5)
    assert by_method["hybrid"]["orientation_mean_mrad"] is None
    # What the 20 poses resolve, as `tablec eval --json` says under "comparison".
    assert records.comparison["reference"] == "hybrid"
    assert [a["method"] for a in records.comparison["against"]] == ["kinematic", "paper"]
    kinematic = records.comparison["against"][0]
    assert kinematic["points"] == 20
    assert kinematic["mean_difference_mm"] == pytest.approx(
        by_method["kinematic"]["position_mean_mm"] - by_method["hybrid"]["position_mean_mm"],
        abs=1e-12,
    )
    out = tmp_path / "figures.json"
    subprocess.run(
        [
            str(tablec), "eval", UR5_GRID, "--validation", UR5_RANDOM, "--columns", UR5_COLUMNS,
            "--robot", UR5 / "robot.toml", "--cell", "30", "--methods", "paper,kinematic,hybrid",
            "--quiet", "--json", str(out),
        ],
        check=True,
        capture_output=True,
    )
    with open(out) as f:
        assert records.comparison == json.load(f)["comparison"]


def test_keep_untrustworthy_equals_tablec(tablec, tmp_path):
    # Every parameter the pivoting keeps, the implausible and the insignificant ones too:
    # a different kinematic model (0.1005 mm, against 0.1004 mm with them held).
    def kinematic(**options):
        return adwi.evaluate(
            UR5_GRID, validation=UR5_RANDOM, columns=UR5_COLUMNS, robot=UR5 / "robot.toml",
            methods="kinematic", **options,
        )

    kept, held = kinematic(keep_untrustworthy=True), kinematic()
    rows = tablec_eval(
        tablec, tmp_path, UR5_GRID, "--validation", UR5_RANDOM, "--columns", UR5_COLUMNS,
        "--robot", UR5 / "robot.toml", "--methods", "kinematic", "--keep-untrustworthy",
    )
    assert_same_figures(kept, rows)
    assert kept[1]["position_mean_mm"] == pytest.approx(0.100511153, abs=1e-9)
    assert held[1]["position_mean_mm"] == pytest.approx(0.100431503, abs=1e-9)


def test_folds_and_dataframes(tmp_path):
    frame = read_frame(KR150 / "samples.csv", comment="#")
    from_frame = adwi.evaluate(frame, folds=5, seed=3, methods=["paper", "idw"])
    from_file = adwi.evaluate(KR150 / "samples.csv", folds=5, seed=3, methods=["paper", "idw"])
    assert from_frame == from_file
    assert [r["method"] for r in from_file] == ["uncompensated", "paper", "idw"]


def test_errors():
    with pytest.raises(adwi.AdwiError, match="validation set"):
        adwi.evaluate(KR150 / "samples.csv")
    with pytest.raises(adwi.AdwiError, match="unknown method 'nope'"):
        adwi.evaluate(KR150 / "samples.csv", folds=3, methods=["nope"])
    with pytest.raises(adwi.AdwiError, match="limit"):
        adwi.evaluate(KR150 / "samples.csv", validation=KR150 / "validation.csv", limit=0)
