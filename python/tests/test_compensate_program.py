"""adwi.compensate_program against tablec compensate: the same bytes, the same report."""

import csv
import subprocess

import pytest

import adwi
from conftest import KR150, REPO, UR5

PROGRAMS = REPO / "tests" / "programs"


@pytest.mark.parametrize("program", ["weld.dat", "weld.src", "cell.mod", "targets.csv"])
def test_the_kr150_programs_match_tablec(tablec, kr150_table, tmp_path, program):
    robot = KR150 / "robot.toml"
    out = tmp_path / f"py-{program}"
    report = tmp_path / "py-report.csv"
    done = adwi.compensate_program(
        kr150_table, PROGRAMS / program, out, report=report, robot=robot
    )
    cli_out = tmp_path / f"cli-{program}"
    cli_report = tmp_path / "cli-report.csv"
    run = subprocess.run(
        [tablec, "compensate", kr150_table, PROGRAMS / program, "-o", cli_out,
         "--robot", robot, "--report", cli_report],
        capture_output=True,
        text=True,
    )
    assert run.returncode == (0 if done.all_corrected else 3), run.stderr
    assert out.read_bytes() == cli_out.read_bytes() == done.output
    assert report.read_text() == cli_report.read_text()
    rows = list(csv.DictReader(cli_report.open()))
    assert [t["status"] for t in done.targets] == [r["status"] for r in rows]
    assert done.summary["text"] in run.stdout
    for t, r in zip(done.targets, rows):
        if t["status"] == "ok":
            assert f"{t['correction_mm']:.6f}" == r["correction_mm"]
            assert all(f"{v:.9f}" == r[f"command_{a}"] for v, a in zip(t["command_mm"], "xyz"))


def test_a_krl_seam_in_the_frames_of_its_config_dat_matches_tablec(tablec, kr150_table, tmp_path):
    robot = KR150 / "robot.toml"
    config = PROGRAMS / "config.dat"
    done = adwi.compensate_program(
        kr150_table, PROGRAMS / "seam.dat", robot=robot, krl_config=config
    )
    cli_out = tmp_path / "cli-seam.dat"
    run = subprocess.run(
        [tablec, "compensate", kr150_table, PROGRAMS / "seam.dat", "-o", cli_out,
         "--robot", robot, "--krl-config", config],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 3, run.stderr
    assert cli_out.read_bytes() == done.output
    statuses = {t["name"]: t["status"] for t in done.targets}
    assert statuses["XP7"] == "frame_unknown" and statuses["XP8"] == "external_axis"
    # The .src's LIN_REL and its two moves to $config.dat's XHOME are counted with them.
    assert (done.summary["corrected"], done.summary["total"]) == (7, 12)
    # ... placed where the .src writes them, the .dat's own targets in the .dat.
    placed = [(t["name"], t["line"], t["column"]) for t in done.targets if t["in_partner"]]
    assert placed == [("XHOME", 25, 6), ("LIN_REL", 49, 1), ("XHOME", 75, 6)]
    assert {(t["name"], t["line"]) for t in done.targets if not t["in_partner"]} >= {("XP1", 18)}
    # Without the configuration, the torch of TOOL_DATA[1] is named, not taken as the flange.
    bare = adwi.compensate_program(kr150_table, PROGRAMS / "seam.dat", robot=robot)
    assert [t for t in bare.targets if t["name"] == "XP1"][0]["detail"].startswith(
        "tool TOOL_DATA[1] not given"
    )


def test_the_ur5_hybrid_program_and_its_frames(ur5_hybrid_table, tmp_path):
    done = adwi.compensate_program(
        ur5_hybrid_table, PROGRAMS / "pick.script", robot=UR5 / "robot.toml"
    )
    # Seven targets corrected; movel(pose_trans(approach, offset)), an offset from a target
    # the correction moves, reported.
    assert (done.summary["corrected"], done.summary["total"]) == (7, 8)
    assert [t["status"] for t in done.targets if t["status"] != "ok"] == ["relative"]
    assert done.output != (PROGRAMS / "pick.script").read_bytes()
    assert all(len(t["command_joints"]) == 6 for t in done.targets if t["status"] == "ok")
    # Without a robot the table's own record of its point on the flange places set_tcp's
    # tool: the same commands (the record is f32).
    alone = adwi.compensate_program(ur5_hybrid_table, PROGRAMS / "pick.script")
    assert [t["status"] for t in alone.targets] == [t["status"] for t in done.targets]
    for a, b in zip(done.targets, alone.targets):
        if a["status"] == "ok" and a["kind"] == "cartesian":
            assert max(abs(x - y) for x, y in zip(a["command_mm"], b["command_mm"])) < 1e-5
    # A table from before that record (format version 3) does not know it: refused at the
    # move, before any work.
    v3 = UR5.parent / "compat" / "v3" / "ur5_hybrid_posture.tbl"
    with pytest.raises(adwi.AdwiError, match=r"pick\.script:8:3: this use names a tool"):
        adwi.compensate_program(v3, PROGRAMS / "pick.script")


def test_a_yaskawa_job_in_its_tool_files_user_frames_and_pulses_matches_tablec(
    tablec, kr150_table, tmp_path
):
    robot = KR150 / "robot.toml"
    pulses = [1456.356, 1456.356, 1350.0, 910.222, 910.222, 555.556]
    done = adwi.compensate_program(
        kr150_table,
        PROGRAMS / "bracket.jbi",
        robot=robot,
        yaskawa_tools={1: [0, 0, 180, 0, 0, 0]},
        yaskawa_users={1: [1600, 250, 750, 0, 0, 30]},
        yaskawa_pulses_per_deg=pulses,
    )
    cli_out = tmp_path / "cli-bracket.jbi"
    run = subprocess.run(
        [tablec, "compensate", kr150_table, PROGRAMS / "bracket.jbi", "-o", cli_out,
         "--robot", robot, "--yaskawa-tool", "1=0,0,180,0,0,0",
         "--yaskawa-user", "1=1600,250,750,0,0,30",
         "--yaskawa-pulses-per-deg", ",".join(str(p) for p in pulses)],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 3, run.stderr
    assert cli_out.read_bytes() == done.output
    assert done.summary["text"] in run.stdout
    assert (done.summary["corrected"], done.summary["total"]) == (9, 15)
    statuses = {t["name"]: t["status"] for t in done.targets}
    assert statuses["C00000"] == "ok" and statuses["C00010"] == "frame_unknown"


def test_a_val3_application_matches_tablec(tablec, kr150_table, tmp_path):
    robot = KR150 / "robot.toml"
    application = PROGRAMS / "staubli" / "weld" / "weld.pjx"
    done = adwi.compensate_program(kr150_table, application, robot=robot)
    cli_out = tmp_path / "cli-weld.dtx"
    run = subprocess.run(
        [tablec, "compensate", kr150_table, application, "-o", cli_out, "--robot", robot],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 3, run.stderr
    assert cli_out.read_bytes() == done.output
    assert done.summary["text"] in run.stdout
    assert (done.summary["corrected"], done.summary["total"]) == (9, 16)
    statuses = {t["name"]: t["status"] for t in done.targets}
    assert statuses["pApproach[0]"] == "ok" and statuses["pLost[0]"] == "frame_unknown"
    assert statuses["pRef[0]"] == "not_moved"


def test_refusals(kr150_table, tmp_path):
    bad = tmp_path / "bad.src"
    bad.write_bytes(b"DEF bad( )\r\nLIN {X 1500,Y 2oo,Z 1200}\r\nEND\r\n")
    with pytest.raises(adwi.AdwiError, match=r"bad\.src:2:15: Y must be a number"):
        adwi.compensate_program(kr150_table, bad)
    with pytest.raises(adwi.AdwiError, match="strict: nothing written"):
        adwi.compensate_program(kr150_table, PROGRAMS / "targets.csv", tmp_path / "o.csv", strict=True)
    assert not (tmp_path / "o.csv").exists()
    with pytest.raises(adwi.AdwiError, match="refusing to write"):
        adwi.compensate_program(kr150_table, PROGRAMS / "targets.csv", PROGRAMS / "targets.csv")
    with pytest.raises(adwi.AdwiError, match="format 'nosuch': one of krl, rapid, urscript, csv, gcode"):
        adwi.compensate_program(kr150_table, PROGRAMS / "targets.csv", format="nosuch")


def fanuc_kr150_by_tablec(tablec, table, program, tmp_path, *options):
    """The bytes tablec writes for a Fanuc program on the KR150-2 with tool frame 1 at the
    flange and the options given."""
    out = tmp_path / "cli.ls"
    subprocess.run(
        [tablec, "compensate", table, program, "-o", out, "--robot", KR150 / "robot.toml",
         "--fanuc-utool", "1=0,0,0,0,0,0", *options],
        check=True,
        capture_output=True,
    )
    return out.read_bytes()


def test_fanuc_turn_axes_are_the_command_lines(tablec, kr150_table, tmp_path):
    # J4 on its turn -1 on a controller whose turn axes are J1, J4, J6 (an R-2000iB's).
    program = tmp_path / "branch.ls"
    program.write_text(
        "/PROG  BRANCH\n/ATTR\nOWNER\t\t= MNEDITOR;\n/MN\n   1:  UFRAME_NUM=0 ;\n"
        "   2:  UTOOL_NUM=1 ;\n   3:L P[1] 100mm/sec FINE    ;\n/POS\nP[1]{\n   GP1:\n"
        "\tUF : 0, UT : 1,\t\tCONFIG : 'F U T, 0, -1, 0',\n"
        "\tX =   1750.000  mm,\tY =    450.000  mm,\tZ =   1250.000  mm,\n"
        "\tW =       .000 deg,\tP =     90.000 deg,\tR =       .000 deg\n};\n/END\n"
    )
    robot = KR150 / "robot.toml"
    tool = {1: [0, 0, 0, 0, 0, 0]}
    default = adwi.compensate_program(kr150_table, program, robot=robot, fanuc_utools=tool)
    assert default.targets[0]["status"] == "invalid"
    assert default.targets[0]["detail"].startswith("turn number -1 of J5 (turn axes 4, 5, 6, the default")
    done = adwi.compensate_program(
        kr150_table, program, robot=robot, fanuc_utools=tool, fanuc_turn_axes=[1, 4, 6]
    )
    assert done.targets[0]["status"] == "ok", done.targets[0]["detail"]
    assert fanuc_kr150_by_tablec(
        tablec, kr150_table, program, tmp_path, "--fanuc-turn-axes", "1,4,6"
    ) == done.output
    with pytest.raises(adwi.AdwiError, match="^fanuc_turn_axes: turn axes 4,4,6: three distinct"):
        adwi.compensate_program(kr150_table, program, robot=robot, fanuc_turn_axes=[4, 4, 6])


def test_fanuc_j23_is_the_command_lines(tablec, kr150_table, tmp_path):
    program = tmp_path / "home.ls"
    program.write_text(
        "/PROG  HOME\n/ATTR\nOWNER\t\t= MNEDITOR;\n/MN\n   1:J P[1] 100% FINE    ;\n/POS\nP[1]{\n"
        "   GP1:\n\tUF : 0, UT : 1,\n\tJ1= 13.846 deg,\tJ2= -73.539 deg,\tJ3= 43.626 deg,\n"
        "\tJ4= 19.659 deg,\tJ5= -45.347 deg,\tJ6= -14.094 deg\n};\n/END\n"
    )
    robot = KR150 / "robot.toml"
    tool = {1: [0, 0, 0, 0, 0, 0]}
    refused = adwi.compensate_program(kr150_table, program, robot=robot, fanuc_utools=tool)
    assert refused.targets[0]["status"] == "invalid"
    assert "give --fanuc-j23 1" in refused.targets[0]["detail"]
    done = adwi.compensate_program(kr150_table, program, robot=robot, fanuc_utools=tool, fanuc_j23=1)
    assert done.targets[0]["status"] == "ok", done.targets[0]["detail"]
    assert fanuc_kr150_by_tablec(
        tablec, kr150_table, program, tmp_path, "--fanuc-j23", "1"
    ) == done.output
    with pytest.raises(adwi.AdwiError, match="J2/J3 factor must be a number from -2 to 2"):
        adwi.compensate_program(kr150_table, program, robot=robot, fanuc_j23=float("nan"))
