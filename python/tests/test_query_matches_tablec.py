"""Table.query and Table.compensate answer as `tablec query --targets` does, row by row:
the same statuses and neighbour counts, and the same numbers to every digit tablec writes
(9 decimals for errors and commands in mm, 12 for rotation vectors in rad; the Python
values, rounded as tablec rounds them, must give the same text)."""

import csv
import subprocess
from pathlib import Path

import numpy as np
import pytest

import adwi
from conftest import KR150, UR5_COLUMNS, UR5_RANDOM, read_frame


def tablec_targets(tablec: Path, table: Path, targets: Path, out: Path, *extra: str):
    """Runs `tablec query TABLE --targets TARGETS -o OUT`; returns its rows."""
    run = subprocess.run(
        [str(tablec), "query", str(table), "--targets", str(targets), "-o", str(out), *extra],
        capture_output=True,
        text=True,
    )
    # 0: every row answered; 3: some rows not (each still written with its status).
    assert run.returncode in (0, 3), run.stderr
    with open(out, newline="") as f:
        return list(csv.DictReader(f))


def formatted(values, decimals):
    return [format(v, f".{decimals}f") for v in values]


def assert_same_answers(rows, result: adwi.Compensation, orientation: bool):
    assert len(rows) == len(result)
    assert list(result.status) == [r["status"] for r in rows]
    assert list(result.neighbours) == [int(r["neighbours"]) for r in rows]
    assert list(result.residual) == [r["residual"] for r in rows]
    assert [e if s == "ok" else "" for e, s in zip(result.evidence, result.status)] == [r["evidence"] for r in rows]
    assert list(result.command_status) == [r["command_status"] for r in rows]
    for i, row in enumerate(rows):
        if row["status"] != "ok":
            assert np.isnan(result.error_mm[i]).all()
            assert np.isnan(result.command_mm[i]).all()
            assert row["pred_dx"] == "" and row["command_x"] == ""
            continue
        assert formatted(result.error_mm[i], 9) == [row["pred_dx"], row["pred_dy"], row["pred_dz"]], i
        assert formatted(result.command_mm[i], 9) == [
            row["command_x"],
            row["command_y"],
            row["command_z"],
        ], i
        # And numerically: within the half unit of the last printed digit.
        np.testing.assert_allclose(
            result.error_mm[i], [float(row[c]) for c in ("pred_dx", "pred_dy", "pred_dz")], rtol=0, atol=5e-10
        )
        if orientation:
            assert formatted(result.orientation_rad[i], 12) == [row["pred_rx"], row["pred_ry"], row["pred_rz"]]
            assert formatted(result.command_rotation_rad[i], 12) == [
                row["command_rx"],
                row["command_ry"],
                row["command_rz"],
            ]
            np.testing.assert_allclose(
                result.orientation_rad[i],
                [float(row[c]) for c in ("pred_rx", "pred_ry", "pred_rz")],
                rtol=0,
                atol=1e-12,
            )
        else:
            assert result.orientation_rad is None
            assert row["pred_rx"] == ""


def kr150_targets(tmp_path: Path) -> Path:
    """The 1000 validation poses (with their configurations), and targets outside the grid,
    on the grid's faces and at the origin."""
    data = read_frame(KR150 / "validation.csv", comment="#")
    points = data[["x", "y", "z"]].to_numpy()
    config = data["config"].to_numpy()
    extra = np.array(
        [[0.0, 0.0, 0.0], [5000.0, 0.0, 0.0], [1350.0, 50.0, 850.0], [2150.0, 850.0, 1650.0],
         [1150.0, 450.0, 1250.0], [2350.0, 450.0, 1250.0], [1749.5, 449.25, 1250.125]]
    )
    points = np.vstack([points, extra])
    config = np.concatenate([config, np.full(len(extra), 4)])
    path = tmp_path / "targets.csv"
    with open(path, "w") as f:
        f.write("x,y,z,config\n")
        for p, c in zip(points, config):
            f.write(",".join(repr(float(v)) for v in p) + f",{int(c)}\n")
    return path


def read_targets(path: Path):
    data = np.genfromtxt(path, delimiter=",", names=True)
    return np.column_stack([data["x"], data["y"], data["z"]]), data["config"].astype(int)


@pytest.mark.parametrize("exact", [False, True], ids=["served", "exact"])
def test_kr150_answers_equal_tablec(tablec, kr150_table, tmp_path, exact):
    targets = kr150_targets(tmp_path)
    extra = ["--exact"] if exact else []
    rows = tablec_targets(tablec, kr150_table, targets, tmp_path / "out.csv", *extra)
    points, config = read_targets(targets)
    table = adwi.Table.open(kr150_table)
    result = table.compensate(points, config=config, exact=exact)
    assert_same_answers(rows, result, orientation=True)
    assert (result.status == "ok").sum() >= 1000
    assert {"outside_grid"} <= set(result.status)
    # query() answers as compensate() does at the targets.
    q = table.query(points, config=config, exact=exact)
    np.testing.assert_array_equal(q.error_mm, result.error_mm)
    np.testing.assert_array_equal(q.orientation_rad, result.orientation_rad)
    np.testing.assert_array_equal(q.status_code, result.status_code)


def test_kr150_without_config_equals_tablec(tablec, kr150_table, tmp_path):
    points = read_frame(KR150 / "validation.csv", comment="#")[["x", "y", "z"]].to_numpy()[:200]
    targets = tmp_path / "targets.csv"
    np.savetxt(targets, points, delimiter=",", header="x,y,z", comments="", fmt="%.17g")
    rows = tablec_targets(tablec, kr150_table, targets, tmp_path / "out.csv")
    result = adwi.Table.open(kr150_table).compensate(points)
    assert_same_answers(rows, result, orientation=True)


def test_ur5_hybrid_answers_equal_tablec(tablec, ur5_hybrid_table, tmp_path):
    """A hybrid table with joint angles in degrees (the file's), first-order commands."""
    rows = tablec_targets(
        tablec, ur5_hybrid_table, UR5_RANDOM, tmp_path / "out.csv", "--columns", UR5_COLUMNS
    )
    data = np.genfromtxt(UR5_RANDOM, delimiter=",", names=True)
    points = np.column_stack([data["x_t"], data["y_t"], data["z_t"]])
    joints = np.column_stack([data[f"joint_{i}"] for i in range(1, 7)])
    table = adwi.Table.open(ur5_hybrid_table)
    assert table.is_hybrid and table.joint_count == 6 and not table.has_orientation
    result = table.compensate(points, joints)
    # No orientation error: the samples measured positions alone, which do not determine
    # the model's.
    assert result.orientation_rad is None
    assert_same_answers(rows, result, orientation=False)
    assert set(result.command_status) == {"first_order"}
    # The same joints in radians give the same answers.
    in_rad = table.query(points, np.radians(joints), joints_unit="rad")
    np.testing.assert_allclose(in_rad.error_mm, result.error_mm, rtol=0, atol=1e-12)
    # Without joints a hybrid table answers missing_joints, as tablec does.
    assert set(table.query(points).status) == {"missing_joints"}


def test_ur5_position_only_equals_tablec(tablec, tmp_path):
    table_path = tmp_path / "ur5.tbl"
    adwi.build(
        Path(UR5_RANDOM).with_name("3D_UR5_uncalibrated_grid_cleaned.csv"),
        table_path,
        columns=UR5_COLUMNS,
    )
    rows = tablec_targets(
        tablec, table_path, UR5_RANDOM, tmp_path / "out.csv", "--columns", UR5_COLUMNS
    )
    data = np.genfromtxt(UR5_RANDOM, delimiter=",", names=True)
    points = np.column_stack([data["x_t"], data["y_t"], data["z_t"]])
    joints = np.column_stack([data[f"joint_{i}"] for i in range(1, 7)])
    result = adwi.Table.open(table_path).compensate(points, joints)
    assert_same_answers(rows, result, orientation=False)
