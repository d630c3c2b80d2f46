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
    # docs/evaluation.md, real UR5 data with the default `harmonics="auto"` (the second
    # harmonic chosen).
    assert by_method["paper"]["position_mean_mm"] == pytest.approx(0.5221, abs=5e-5)
    assert by_method["hybrid"]["position_mean_mm"] == pytest.approx(0.0838, abs=5e-5)
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
    # a different kinematic model (0.1005 mm, against 0.1004 mm with them held; geometry
    # alone, no joint-space terms).
    def kinematic(**options):
        return adwi.evaluate(
            UR5_GRID, validation=UR5_RANDOM, columns=UR5_COLUMNS, robot=UR5 / "robot.toml",
            methods="kinematic", harmonics=0, **options,
        )

    kept, held = kinematic(keep_untrustworthy=True), kinematic()
    rows = tablec_eval(
        tablec, tmp_path, UR5_GRID, "--validation", UR5_RANDOM, "--columns", UR5_COLUMNS,
        "--robot", UR5 / "robot.toml", "--methods", "kinematic", "--keep-untrustworthy",
        "--harmonics", "0",
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


def by_region_table(text):
    """The rows of the second figures table `tablec eval --by-region` prints: method,
    predicted, missed and the four position figures, as printed."""
    tables = [t for t in text.split("\nmethod ") if "│" in t][1:]
    assert len(tables) == 2, text
    rows = {}
    for line in tables[1].splitlines()[1:]:
        cells = line.replace("│", " ").split()
        if len(cells) < 7 or not cells[1].isdigit():
            continue
        rows[cells[0]] = cells[1:7]
    return rows


def test_by_region_returns_the_table_tablec_prints(tablec, tmp_path):
    options = dict(folds=3, seed=1, methods=["paper", "idw"])
    records = adwi.evaluate(KR150 / "samples.csv", by_region=True, **options)
    assert records.by_region is not None
    assert [r["method"] for r in records.by_region] == ["uncompensated", "paper", "idw"]
    assert set(records.by_region[0]) == set(records[0])
    # Held out by region, not the random folds again.
    assert records.by_region[1]["position_mean_mm"] != records[1]["position_mean_mm"]
    printed = subprocess.run(
        [
            str(tablec), "eval", KR150 / "samples.csv", "--folds", "3", "--seed", "1",
            "--methods", "paper,idw", "--by-region",
        ],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    rows = by_region_table(printed)
    assert sorted(rows) == ["idw", "paper", "uncompensated"]
    for record in records.by_region:
        row = rows[record["method"]]
        assert int(row[0]) == record["predicted"]
        assert int(row[1]) == record["not_predicted"]
        for printed_value, key in zip(row[2:], ["mean", "rms", "p95", "max"]):
            assert printed_value == format(record[f"position_{key}_mm"], ".4f"), key
    # Without by_region there is no second evaluation.
    assert adwi.evaluate(KR150 / "samples.csv", **options).by_region is None


def test_a_refused_option_is_named_by_its_keyword_alone(tmp_path):
    cases = [
        (
            lambda: adwi.evaluate(
                KR150 / "samples.csv", validation=KR150 / "validation.csv", by_region=True
            ),
            "by_region",
        ),
        (
            lambda: adwi.evaluate(
                KR150 / "samples.csv", folds=3, register_validation_apart=True
            ),
            "register_validation_apart",
        ),
        (
            lambda: adwi.build(
                KR150 / "samples.csv", tmp_path / "t.tbl", tune=True, tune_folds=1
            ),
            "tune_folds",
        ),
        (lambda: adwi.evaluate(KR150 / "samples.csv", folds=3, base_link="b"), "base_link"),
    ]
    for call, keyword in cases:
        with pytest.raises(adwi.AdwiError) as refused:
            call()
        message = str(refused.value)
        assert keyword in message, message
        assert "--" + keyword.replace("_", "-") not in message, message
