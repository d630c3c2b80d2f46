"""adwi.build: the same tables, options and errors as `tablec build`."""

import os
import subprocess

import numpy as np
import pandas as pd
import pytest

import adwi
from conftest import (
    KR150,
    KR150_OPTIONS,
    PAPER,
    UR5,
    UR5_COLUMNS,
    UR5_GRID,
    UR5_HYBRID_OPTIONS,
    read_frame,
)

# The worked example's target and prediction (docs/method.md; tests/worked_example.rs).
P1 = [2000.0, 700.0, 1000.0]
P1_PREDICTED_MM = [0.044584991, 0.995639127, -0.230310237]


def test_default_table_is_byte_identical_to_tablec(tablec, tmp_path):
    ours = tmp_path / "adwi.tbl"
    report = adwi.build(KR150 / "samples.csv", ours)
    out = tmp_path / "tablec.tbl"
    subprocess.run(
        [str(tablec), "build", "--quiet", str(KR150 / "samples.csv"), "-o", str(out)],
        check=True,
    )
    assert out.read_bytes() == ours.read_bytes()
    assert report.served_field in ("method", "kriging")


def test_table_is_byte_identical_to_tablec(tablec, kr150_table, tmp_path):
    out = tmp_path / "tablec.tbl"
    subprocess.run(
        [str(tablec), "build", "--quiet", str(KR150 / "samples.csv"), "-o", str(out),
         "--served-field", "method"],
        check=True,
    )
    assert out.read_bytes() == kr150_table.read_bytes()


def test_tune_chooses_as_tablec_and_records_the_choice(tablec, tmp_path):
    ours = tmp_path / "ours.tbl"
    report = adwi.build(KR150 / "samples.csv", ours, tune=True, tune_folds=3)
    theirs = tmp_path / "tablec.tbl"
    subprocess.run(
        [str(tablec), "build", "--quiet", str(KR150 / "samples.csv"), "-o", str(theirs),
         "--tune", "--tune-folds", "3"],
        check=True,
    )
    assert ours.read_bytes() == theirs.read_bytes()
    assert report.tuning["folds"] == 3
    assert 0.0 < report.tuning["cv_mean_mm"] < 0.2
    assert 0.0 < report.tuning["served_cv_mean_mm"] < 0.2
    plain = adwi.build(KR150 / "samples.csv", tmp_path / "plain.tbl", served_field="method")
    assert plain.tuning is None
    with pytest.raises(adwi.AdwiError, match="^tune chooses k and the radius ε: give tune, or k/radius"):
        adwi.build(KR150 / "samples.csv", tmp_path / "both.tbl", tune=True, k=8)


def test_kriging_served_field_is_byte_identical_to_tablec(tablec, tmp_path):
    ours = tmp_path / "ours.tbl"
    report = adwi.build(KR150 / "samples.csv", ours, served_field="kriging")
    assert report.served_field == "kriging"
    # x, y, z and the orientation's three, each with its own length scale and nugget.
    assert len(report.served_kriging) == 6
    for choice in report.served_kriging:
        assert choice["length_scale_mm"] > 0 and choice["relative_nugget"] > 0
        assert choice["modulation"] == 0
        assert choice["vertical_scale"] in (0.25, 0.5, 1.0, 2.0)
    theirs = tmp_path / "tablec.tbl"
    subprocess.run(
        [str(tablec), "build", "--quiet", str(KR150 / "samples.csv"), "-o", str(theirs),
         "--served-field", "kriging"],
        check=True,
    )
    assert ours.read_bytes() == theirs.read_bytes()
    method = adwi.build(KR150 / "samples.csv", tmp_path / "m.tbl", served_field="method")
    assert method.served_field == "method" and method.served_kriging == []
    with pytest.raises(adwi.AdwiError, match="^served_field: 'spline': choose auto, method or kriging"):
        adwi.build(KR150 / "samples.csv", tmp_path / "bad.tbl", served_field="spline")
    # kriging-tool-axis is the older name of kriging: without a model, a field of position.
    axis = adwi.build(KR150 / "samples.csv", tmp_path / "axis.tbl",
                      served_field="kriging-tool-axis")
    assert axis.served_field == "kriging"
    assert (tmp_path / "axis.tbl").read_bytes() == ours.read_bytes()


def test_options_reach_the_table_as_tablec_gives_them(tablec, tmp_path):
    options = ["--cell", "40", "--radius", "190", "--k", "6", "--w2", "0.2", "--power", "1.5",
               "--no-consistency-screen", "--bounds", "1300,0,800,2200,900,1700",
               "--joint-radius", "30"]
    out = tmp_path / "tablec.tbl"
    subprocess.run(
        [str(tablec), "build", "--quiet", str(KR150 / "samples.csv"), "-o", str(out), *options],
        check=True,
    )
    report = adwi.build(
        KR150 / "samples.csv",
        tmp_path / "adwi.tbl",
        cell=40,
        radius=190,
        k=6,
        w2=0.2,
        power=1.5,
        no_consistency_screen=True,
        bounds=(1300, 0, 800, 2200, 900, 1700),
        joint_radius=30,
    )
    assert (tmp_path / "adwi.tbl").read_bytes() == out.read_bytes()
    assert report.w1 == pytest.approx(0.8) and report.k == 6 and not report.consistency_screen
    assert report.cell_mm == 40 and not report.cell_derived and not report.radius_derived
    assert report.joint_radius_deg == pytest.approx(30)


def test_report(kr150_table):
    table = adwi.Table.open(kr150_table)
    report = adwi.build(KR150 / "samples.csv", kr150_table.with_name("again.tbl"), **KR150_OPTIONS)
    assert report.samples == 729 == table.sample_count
    assert report.bytes == os.path.getsize(kr150_table)
    assert report["cells"] == report.cells == int(np.prod(report.grid_dims))
    assert 0 < report.covered_cells <= report.cells
    assert report.radius_derived and report.cell_derived
    assert report.spacing_mm == pytest.approx(100.0)
    assert report.hybrid is False and report.calibration is None and report.repeats is None
    assert table.grid["dims"] == report.grid_dims
    assert table.has_orientation and table.has_config and not table.is_hybrid
    assert table.method["k"] == 8 and table.method["w1"] == 0.87
    assert "cells" in repr(report)


def test_worked_example(tmp_path):
    path = tmp_path / "p1.tbl"
    adwi.build(PAPER / "worked_example_p1.csv", path)
    result = adwi.Table.open(path).query(P1, exact=True)
    assert list(result.status) == ["ok"] and result.neighbours[0] == 8
    np.testing.assert_allclose(result.error_mm[0], P1_PREDICTED_MM, rtol=0, atol=1e-9)
    assert result.orientation_rad is None


def test_dataframe_gives_the_same_table_as_the_file(kr150_table, tmp_path):
    frame = read_frame(KR150 / "samples.csv", comment="#")
    adwi.build(frame, tmp_path / "frame.tbl", **KR150_OPTIONS)
    assert (tmp_path / "frame.tbl").read_bytes() == kr150_table.read_bytes()


def test_array_gives_the_same_table_as_its_columns(tmp_path):
    frame = read_frame(KR150 / "samples.csv", comment="#")
    columns = ["x", "y", "z", "dx", "dy", "dz"] + [f"j{i}" for i in range(1, 7)]
    adwi.build(frame[columns], tmp_path / "frame.tbl", **KR150_OPTIONS)
    report = adwi.build(frame[columns].to_numpy(), tmp_path / "array.tbl", **KR150_OPTIONS)
    assert (tmp_path / "array.tbl").read_bytes() == (tmp_path / "frame.tbl").read_bytes()
    assert report.source == "<samples array>"
    table = adwi.Table.open(tmp_path / "array.tbl")
    assert not table.has_orientation and not table.has_config


def test_dataframe_with_mapped_columns(tmp_path):
    frame = read_frame(UR5_GRID)
    adwi.build(UR5_GRID, tmp_path / "file.tbl", columns=UR5_COLUMNS, served_field="method")
    mapping = dict(item.split("=") for item in UR5_COLUMNS.split(","))
    adwi.build(frame, tmp_path / "frame.tbl", columns=mapping, served_field="method")
    assert (tmp_path / "frame.tbl").read_bytes() == (tmp_path / "file.tbl").read_bytes()


def test_bad_row_names_file_line_and_column(tmp_path):
    samples = tmp_path / "samples.csv"
    samples.write_text("x,y,z,dx,dy,dz\n0,0,0,0,0,0\n1,0,0,abc,0,0\n")
    with pytest.raises(adwi.AdwiError, match=r"samples\.csv:3:4 \(column 'dx'\): not a number: 'abc'"):
        adwi.build(samples, tmp_path / "t.tbl")
    assert not (tmp_path / "t.tbl").exists()
    samples.write_text("x,y,z,dx,dy,dz\n0,0,0,0,0,0\n1,0,0,0,0\n")
    with pytest.raises(adwi.AdwiError, match=r"samples\.csv:3: 5 fields where the header has 6"):
        adwi.build(samples, tmp_path / "t.tbl")
    assert issubclass(adwi.AdwiError, ValueError)


def test_bad_array_value_names_row_and_column(tmp_path):
    array = np.zeros((4, 6))
    array[:, 0] = [0, 100, 200, 300]
    array[2, 4] = np.nan
    with pytest.raises(adwi.AdwiError, match=r"<samples array>:4:5 \(column 'dy'\)"):
        adwi.build(array, tmp_path / "t.tbl")
    with pytest.raises(adwi.AdwiError, match=r"shape is \(4, 5\)"):
        adwi.build(np.zeros((4, 5)), tmp_path / "t.tbl")


def test_never_overwrites_an_input(tmp_path):
    samples = tmp_path / "samples.csv"
    samples.write_bytes((KR150 / "samples.csv").read_bytes())
    before = samples.read_bytes()
    with pytest.raises(adwi.AdwiError, match="refusing to write"):
        adwi.build(samples, samples)
    link = tmp_path / "link.csv"
    os.link(samples, link)
    with pytest.raises(adwi.AdwiError, match="through a link"):
        adwi.build(samples, link)
    robot = tmp_path / "robot.toml"
    robot.write_bytes((UR5 / "robot.toml").read_bytes())
    with pytest.raises(adwi.AdwiError, match="refusing to write"):
        adwi.build(UR5_GRID, robot, columns=UR5_COLUMNS, robot=robot)
    assert samples.read_bytes() == before
    assert robot.read_bytes() == (UR5 / "robot.toml").read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.csv", "robot.toml", "samples.csv"]


def test_replaces_an_existing_table_atomically(kr150_table, tmp_path):
    out = tmp_path / "t.tbl"
    adwi.build(PAPER / "worked_example_p1.csv", out)
    held = adwi.Table.open(out)  # mapped while replaced
    adwi.build(KR150 / "samples.csv", out, **KR150_OPTIONS)
    assert out.read_bytes() == kr150_table.read_bytes()
    assert held.sample_count == 8 and adwi.Table.open(out).sample_count == 729
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.tbl"]


def test_option_errors(tmp_path):
    with pytest.raises(adwi.AdwiError, match="needs the robot file"):
        adwi.build(UR5_GRID, tmp_path / "t.tbl", columns=UR5_COLUMNS, hybrid=True)
    with pytest.raises(adwi.AdwiError, match="give the robot file"):
        adwi.build(UR5_GRID, tmp_path / "t.tbl", columns=UR5_COLUMNS, compliance=True)
    # Options are the jobs' own: an unknown one is refused with the known ones, a value
    # of the wrong kind with its name.
    with pytest.raises(adwi.AdwiError, match="no option 'cels'.*cell"):
        adwi.build(KR150 / "samples.csv", tmp_path / "t.tbl", cels=40)
    with pytest.raises(adwi.AdwiError, match="^k: invalid value: integer `-1`"):
        adwi.build(KR150 / "samples.csv", tmp_path / "t.tbl", k=-1)
    with pytest.raises(adwi.AdwiError, match="threads"):
        adwi.build(KR150 / "samples.csv", tmp_path / "t.tbl", threads=100000)
    with pytest.raises(adwi.AdwiError, match="delimiter"):
        adwi.build(KR150 / "samples.csv", tmp_path / "t.tbl", delimiter="pipe")
    with pytest.raises(adwi.AdwiError, match="missing column"):
        adwi.build(UR5_GRID, tmp_path / "t.tbl")
    with pytest.raises(adwi.AdwiError, match="six numbers"):
        adwi.build(KR150 / "samples.csv", tmp_path / "t.tbl", bounds=(0, 0, 0))
    with pytest.raises(adwi.AdwiError, match="cannot open table"):
        adwi.Table.open(KR150 / "samples.csv")
    assert not (tmp_path / "t.tbl").exists()


def test_hybrid_report(ur5_hybrid_table):
    report = adwi.build(
        UR5_GRID,
        ur5_hybrid_table.with_name("again.tbl"),
        columns=UR5_COLUMNS,
        **UR5_HYBRID_OPTIONS,
    )
    assert report.hybrid and report.calibration is not None
    c = report.calibration
    assert c["position_rms_mm"] < c["initial_position_rms_mm"]
    assert c["identified"] and all(isinstance(v, float) for v in c["identified"].values())
    assert ur5_hybrid_table.with_name("again.tbl").read_bytes() == ur5_hybrid_table.read_bytes()


def test_compliant_hybrid_table_is_byte_identical_to_tablec(tablec, tmp_path):
    ours = tmp_path / "ours.tbl"
    report = adwi.build(
        UR5_GRID,
        ours,
        columns=UR5_COLUMNS,
        compliance=True,
        **UR5_HYBRID_OPTIONS,
    )
    theirs = tmp_path / "tablec.tbl"
    subprocess.run(
        [str(tablec), "build", "--quiet", str(UR5_GRID), "-o", str(theirs),
         "--columns", UR5_COLUMNS, "--robot", str(UR5 / "robot.toml"),
         "--compliance", "--cell", "30", "--served-field", "method", "--posture", "off",
         "--harmonics", "0"],
        check=True,
    )
    assert ours.read_bytes() == theirs.read_bytes()
    assert "compliance2" in report.calibration["identified"]
    plain = tmp_path / "plain.tbl"
    adwi.build(UR5_GRID, plain, columns=UR5_COLUMNS, **UR5_HYBRID_OPTIONS)
    assert plain.read_bytes() != ours.read_bytes()
    with pytest.raises(adwi.AdwiError, match="no link masses"):
        adwi.build(KR150 / "samples.csv", tmp_path / "k.tbl", robot=KR150 / "robot.toml",
                   compliance=True)
