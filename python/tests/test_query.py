"""Table.query: shapes, units, statuses, threads."""

import threading

import numpy as np
import pytest

import adwi
from conftest import KR150


def test_shapes_and_types(kr150_table):
    table = adwi.Table.open(kr150_table)
    points = np.array([[1750.0, 450.0, 1250.0], [0.0, 0.0, 0.0], [np.nan, 0.0, 0.0]])
    r = table.query(points)
    assert r.error_mm.shape == (3, 3) and r.error_mm.dtype == np.float64
    assert r.orientation_rad.shape == (3, 3)
    assert r.status.shape == (3,) and list(r.status) == ["ok", "outside_grid", "invalid_input"]
    assert list(r.status_code) == [0, 1, 3]
    assert list(r.ok) == [True, False, False]
    assert r.neighbours.shape == (3,) and r.neighbours[0] > 0
    assert np.isnan(r.error_mm[1:]).all() and np.isfinite(r.error_mm[0]).all()
    assert len(r) == 3 and "1 ok" in repr(r)
    # One point as a (3,) sequence; lists and integer arrays are taken as float64.
    one = table.query([1750, 450, 1250])
    np.testing.assert_array_equal(one.error_mm[0], r.error_mm[0])
    # A non-contiguous view.
    wide = np.zeros((3, 6))
    wide[:, ::2] = points
    np.testing.assert_array_equal(table.query(wide[:, ::2]).status_code, r.status_code)
    empty = table.query(np.zeros((0, 3)))
    assert empty.error_mm.shape == (0, 3) and empty.status.shape == (0,)


def test_refuses_bad_shapes(kr150_table):
    table = adwi.Table.open(kr150_table)
    with pytest.raises(adwi.AdwiError, match=r"\(N, 3\)"):
        table.query(np.zeros((4, 2)))
    with pytest.raises(adwi.AdwiError, match="rows"):
        table.query(np.zeros((4, 3)), np.zeros((3, 6)))
    with pytest.raises(adwi.AdwiError, match="joints_unit"):
        table.query(np.zeros((4, 3)), np.zeros((4, 6)), joints_unit="grad")
    with pytest.raises(adwi.AdwiError, match="254"):
        table.query(np.zeros((1, 3)), config=[300])


def test_hybrid_table_takes_its_joint_count(ur5_hybrid_table):
    table = adwi.Table.open(ur5_hybrid_table)
    with pytest.raises(adwi.AdwiError, match="6 joint values"):
        table.query(np.zeros((4, 3)), np.zeros((4, 5)))
    r = table.query(np.zeros((2, 3)), np.zeros((2, 6)))
    # The UR5's samples measured position alone, which does not determine the model's
    # orientation error: the table serves none, as a position-only table.
    assert r.error_mm.shape == (2, 3) and r.orientation_rad is None


def test_compensated_command_lands_on_the_target(kr150_table):
    table = adwi.Table.open(kr150_table)
    rng = np.random.default_rng(1)
    points = rng.uniform([1400, 100, 900], [2100, 800, 1600], size=(500, 3))
    c = table.compensate(points)
    assert (c.command_status == "converged").all()
    landing = c.command_mm + table.query(c.command_mm).error_mm
    np.testing.assert_allclose(landing, points, rtol=0, atol=1e-6)
    assert (c.residual_mm <= 1e-6).all() and (c.iterations >= 1).all()


def test_served_and_exact_tiers_are_close(kr150_table):
    table = adwi.Table.open(kr150_table)
    rng = np.random.default_rng(2)
    points = rng.uniform([1400, 100, 900], [2100, 800, 1600], size=(2000, 3))
    served = table.query(points)
    exact = table.query(points, exact=True)
    assert served.ok.all() and exact.ok.all()
    # The served field blends the method's values at the grid's nodes: within a tenth of
    # a millimetre of the method itself here, errors being 1-3 mm.
    assert np.abs(served.error_mm - exact.error_mm).max() < 0.1
    assert (served.neighbours == 8).all()


def test_threads_query_one_table_at_once(kr150_table):
    table = adwi.Table.open(kr150_table)
    rng = np.random.default_rng(3)
    points = rng.uniform([1400, 100, 900], [2100, 800, 1600], size=(200_000, 3))
    expected = table.query(points).error_mm
    results = [None] * 4

    def work(i):
        results[i] = table.query(points).error_mm

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for r in results:
        np.testing.assert_array_equal(r, expected)
