"""Shared fixtures: the repository's shipped data, and the tablec binary to compare with."""

import json
import os
import subprocess
from pathlib import Path

import pytest

#: The repository root (this file is python/tests/conftest.py).
REPO = Path(__file__).resolve().parents[2]
KR150 = REPO / "tables" / "kr150-2"
PAPER = REPO / "tables" / "paper"
UR5 = REPO / "tables" / "ur5"
UR5_GRID = UR5 / "measurements" / "3D_UR5_uncalibrated_grid_cleaned.csv"
# The options of the shared tables (fixtures below): choosing the served field, the
# posture term and the joint-space terms cross-validates the whole build several times,
# which the tests of those choices do once each.
KR150_OPTIONS = {"served_field": "method"}
UR5_HYBRID_OPTIONS = {
    "robot": UR5 / "robot.toml",
    "cell": 30,
    "served_field": "method",
    "posture": "off",
    "harmonics": 0,
}
UR5_RANDOM = UR5 / "measurements" / "3D_UR5_uncalibrated_random_cleaned.csv"
UR5_COLUMNS = (
    "x=x_t,y=y_t,z=z_t,dx=x_dif,dy=y_dif,dz=z_dif,"
    "j1=joint_1,j2=joint_2,j3=joint_3,j4=joint_4,j5=joint_5,j6=joint_6"
)
#: The IPA UR10's 6-D laser-tracker measurements, in the tracker's frame (docs/tracker.md):
#: series B and C were taken from one tracker position.
UR10 = REPO / "tables" / "ur10"
UR10_B = UR10 / "measurements" / "Series_B" / "measurements_joint_configurations.csv"
UR10_C = UR10 / "measurements" / "Series_C" / "measurements_random_poses.csv"
UR10_TRACKER_COLUMNS = (
    "j1=shoulder_pan_joint:rad,j2=shoulder_lift_joint:rad,j3=elbow_joint:rad,"
    "j4=wrist_1_joint:rad,j5=wrist_2_joint:rad,j6=wrist_3_joint:rad,"
    "mx=measurement_x,my=measurement_y,mz=measurement_z,"
    "mex=measurement_rx:deg,mey=measurement_ry:deg,mez=measurement_rz:deg"
)


@pytest.fixture(scope="session")
def tablec() -> Path:
    """The tablec binary: $TABLEC if set, otherwise built from this repository with
    `cargo build --release --bin tablec` (a no-op when it is up to date)."""
    if os.environ.get("TABLEC"):
        return Path(os.environ["TABLEC"])
    subprocess.run(
        ["cargo", "build", "--release", "--locked", "--quiet", "--bin", "tablec"],
        cwd=REPO,
        check=True,
    )
    metadata = subprocess.run(
        ["cargo", "metadata", "--format-version", "1", "--no-deps"],
        cwd=REPO,
        check=True,
        capture_output=True,
        text=True,
    )
    target = Path(json.loads(metadata.stdout)["target_directory"])
    binary = target / "release" / "tablec"
    assert binary.exists(), binary
    return binary


@pytest.fixture(scope="session")
def kr150_table(tmp_path_factory) -> Path:
    """The KR150-2 table with the method's served field, built by adwi.build: the tests
    that use it are about the table, not about the choice of field (test_build.py checks
    the default build, choice included, against tablec's)."""
    import adwi

    path = tmp_path_factory.mktemp("kr150") / "kr150.tbl"
    adwi.build(KR150 / "samples.csv", path, **KR150_OPTIONS)
    return path


@pytest.fixture(scope="session")
def ur5_hybrid_table(tmp_path_factory) -> Path:
    """The UR5 hybrid table (30 mm cells) with the method's served field and no posture
    term, built by adwi.build: its tests are about hybrid tables, not the choice of field."""
    import adwi

    path = tmp_path_factory.mktemp("ur5") / "ur5-hybrid.tbl"
    adwi.build(UR5_GRID, path, columns=UR5_COLUMNS, **UR5_HYBRID_OPTIONS)
    return path


def read_frame(path, **kwargs):
    """A CSV as a DataFrame, every number parsed to the last bit (pandas 3 does so by
    default and deprecates the option)."""
    import pandas as pd

    if int(pd.__version__.split(".")[0]) < 3:
        kwargs.setdefault("float_precision", "round_trip")
    return pd.read_csv(path, **kwargs)
