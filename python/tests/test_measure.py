"""adwi.plan and adwi.iso9283 run the jobs tablec plan and tablec iso9283 run: the same
files, the same figures."""

import json
import subprocess

import numpy as np
import pytest

import adwi

from conftest import KR150, UR5


def test_plan_writes_the_file_tablec_writes(tablec, tmp_path):
    options = ["--min", "-600,-600,0", "--max", "600,600,700", "--count", "12", "--seed", "4"]
    subprocess.run(
        [tablec, "plan", "--robot", UR5 / "robot.toml", *options, "-q", "-o", tmp_path / "t.csv"],
        check=True,
        capture_output=True,
    )
    planned = adwi.plan(
        tmp_path / "p.csv",
        robot=UR5 / "robot.toml",
        min=[-600, -600, 0],
        max=[600, 600, 700],
        count=12,
        seed=4,
    )
    assert (tmp_path / "p.csv").read_bytes() == (tmp_path / "t.csv").read_bytes()
    assert len(planned["joints_rad"]) == 12
    positions = np.asarray(planned["position_mm"])
    assert np.all(positions >= [-600, -600, 0]) and np.all(positions <= [600, 600, 700])
    # No 12 candidates have a lower mean prediction variance than the bound.
    assert 0 < planned["variance_bound"] <= planned["mean_variance"]


def test_plan_refuses_a_request_too_large_with_its_figure(tmp_path):
    with pytest.raises(adwi.AdwiError, match="100000 poses"):
        adwi.plan(tmp_path / "p.csv", robot=UR5 / "robot.toml", min=[0, 0, 0], max=[1, 1, 1],
                  count=100_000)


def test_iso9283_gives_tablec_s_figures(tablec, tmp_path):
    written = adwi.iso9283(cube=[1750, 450, 1250, 600], cycles=5, output=tmp_path / "plan.csv")
    assert written["written"] == [str(tmp_path / "plan.csv")]
    lines = [l for l in (tmp_path / "plan.csv").read_text().splitlines() if not l.startswith("#")]
    rng = np.random.default_rng(3)
    rows = [lines[0] + ",mx,my,mz"]
    for line in lines[1:]:
        xyz = np.array([float(v) for v in line.split(",")[2:5]])
        attained = xyz + [0.2, -0.1, 0.05] + rng.normal(0, 0.02, 3)
        rows.append(line + "," + ",".join(f"{v:.4f}" for v in attained))
    cycles = tmp_path / "cycles.csv"
    cycles.write_text("\n".join(rows) + "\n")
    subprocess.run(
        [tablec, "iso9283", cycles, "--json", tmp_path / "t.json"], check=True, capture_output=True
    )
    expected = json.loads((tmp_path / "t.json").read_text())
    report = adwi.iso9283(cycles, report=tmp_path / "page")
    page = (tmp_path / "page" / "index.html").read_text()
    for p in expected["positions"]:
        assert f"<td>{p['ap_p_mm']:.4f}</td>" in page and f"<td>{p['rp_l_mm']:.4f}</td>" in page
    assert [p["name"] for p in report["positions"]] == ["P1", "P2", "P3", "P4", "P5"]
    for got, want in zip(report["positions"], expected["positions"]):
        for key in ("n", "ap_p_mm", "ap_x_mm", "rp_l_mm", "ap_a_deg"):
            assert got[key] == want[key], key
    assert report["distance"] == expected["distance"]
    assert abs(report["positions"][0]["ap_x_mm"] - 0.2) < 0.05
    assert report["compensated"] is None


def test_iso9283_with_a_table_reports_the_compensation(kr150_table, tmp_path):
    adwi.iso9283(cube=[1750, 450, 1250, 600], cycles=3, output=tmp_path / "plan.csv")
    lines = [l for l in (tmp_path / "plan.csv").read_text().splitlines() if not l.startswith("#")]
    rows = [lines[0] + ",mx,my,mz"] + [line + "," + ",".join(line.split(",")[2:5]) for line in lines[1:]]
    (tmp_path / "cycles.csv").write_text("\n".join(rows) + "\n")
    report = adwi.iso9283(tmp_path / "cycles.csv", table=kr150_table)
    compensated = report["compensated"]["positions"]
    # Attained exactly as commanded: what remains is the table's predicted error, its
    # repeatability nothing.
    assert all(p["ap_p_mm"] > 0.5 and p["rp_l_mm"] < 1e-9 for p in compensated)


def test_calibrate_reports_the_truth_comparison_tablec_writes(tablec, tmp_path):
    robot = KR150 / "robot.toml"
    scenario = KR150 / "scenario_geometric.toml"
    samples = tmp_path / "measured.csv"
    subprocess.run(
        [tablec, "simulate", "--robot", robot, "--scenario", scenario, "--min", "1350,50,850",
         "--max", "2150,850,1650", "--random", "30", "--abc", "0,90,0", "--seed", "1",
         "-o", samples],
        check=True,
        capture_output=True,
    )
    truth = dict(true_scenario=scenario, true_at=KR150 / "validation.csv")
    subprocess.run(
        [tablec, "calibrate", samples, "--robot", robot, "--true-scenario", scenario,
         "--true-at", truth["true_at"], "--json", tmp_path / "t.json"],
        check=True,
        capture_output=True,
    )
    expected = json.loads((tmp_path / "t.json").read_text())
    got = adwi.calibrate(samples, robot=robot, **truth)
    for key, value in expected.items():
        assert got[key] == value, key
    t = got["truth"]
    assert t["poses"] == 1000
    assert 0 < t["position_mean_mm"] <= t["position_rms_mm"] <= t["position_max_mm"]
    lengths = [p for p in t["parameters"] if p["unit"] == "mm"]
    rms = np.sqrt(np.mean([(p["identified"] - p["truth"]) ** 2 for p in lengths]))
    assert abs(rms - t["length_rms_mm"]) < 1e-12
    assert adwi.calibrate(samples, robot=robot)["truth"] is None
