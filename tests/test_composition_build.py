"""Offline build (qfg.composition.build), tensor files (qfg.composition.store) and the CLI."""

import zipfile

import numpy as np
import pytest
import shapely
from hypothesis import example, given, settings
from hypothesis import strategies as st
from shapely.geometry import box

from qfg import composition as qc
from qfg import partitions as qp
from qfg.composition import build as qb
from qfg.geometry import from_frame, to_frame
from qfg.harness.cli import main as cli_main

B = np.array([0.0, 1.0])


def _polys(name):
    return np.asarray(qp.get(name).polygons, dtype=object)


@settings(max_examples=30, deadline=None)
@given(name=st.sampled_from(["edc", "tpcc", "fdc"]), u=st.floats(0.01, 0.99),
       v=st.floats(0.01, 0.99))
# Cases where the former reference (transform the partition's polygons, then intersect) raised
# GEOSException (issue 11, item 6).
@example(name="tpcc", u=0.7042503817755887, v=0.7833715312310431)
@example(name="tpcc", u=0.6211448987508755, v=0.3799141629017853)
def test_area_rows_and_columns_add_up_to_window_overlaps(name, u, v):
    # sum_j area(BC_j cap AB_k) = area(AB_k cap BC window) and
    # sum_k area(BC_j cap AB_k) = area(BC_j cap AB window), computed directly with shapely.
    # The reference only ever intersects the partition's own (valid) polygons with a rectangle
    # mapped by the similarity, never a transformed partition polygon: rounding can make those
    # invalid ("unable to assign free hole to a shell"), which the build repairs but a reference
    # must not depend on. Areas scale by |BC|^2 from the BC frame to the AB frame.
    part = qp.get(name)
    x0, x1, y0, y1 = part.window
    C = np.array([x0 + u * (x1 - x0), y0 + v * (y1 - y0)])
    if np.hypot(*(C - B)) < 1e-3:
        return
    areas = qb.intersection_areas(_polys(name), C[None])[0]
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
    bc_window = shapely.Polygon(from_frame(corners, B, C))  # the BC window in the AB frame
    want_k = shapely.area(shapely.intersection(_polys(name), bc_window))
    np.testing.assert_allclose(areas.sum(axis=0), want_k, rtol=1e-7, atol=1e-9)
    ab_window = shapely.Polygon(to_frame(corners, B, C))  # the AB window in the BC frame
    want_j = shapely.area(shapely.intersection(_polys(name), ab_window)) * np.sum((C - B) ** 2)
    np.testing.assert_allclose(areas.sum(axis=1), want_j, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("name, C", [("edc", (0.7, 0.2)), ("edc", (-1.5, 2.4)),
                                     ("tpcc", (0.3, 1.6)), ("fdc", (-0.5, -0.4))])
def test_areas_match_exact_lookup_on_a_grid(name, C):
    # Independent of the polygons: classify a fine grid of D with the exact lookups and the
    # to_frame transform, count cells per (j, k).
    part = qp.get(name)
    x0, x1, y0, y1 = part.window
    h = 0.004
    xs, ys = np.arange(x0 + h / 2, x1, h), np.arange(y0 + h / 2, y1, h)
    D = np.stack(np.meshgrid(xs, ys), axis=-1).reshape(-1, 2)
    C = np.asarray(C, dtype=float)
    Dbc = to_frame(D, B, C)
    ok = part.in_window(Dbc)
    m = part.n_states
    counts = np.bincount(part.state_of(Dbc[ok]) * m + part.state_of(D[ok]), minlength=m * m)
    grid = counts.reshape(m, m) * h * h
    areas = qb.intersection_areas(_polys(name), C[None])[0]
    assert np.abs(grid - areas).max() < 0.01
    assert abs(grid.sum() - areas.sum()) < 0.01


def test_sample_state_is_in_state_and_spread():
    part = qp.get("edc")
    pts = qb.sample_state(part, 12, 512, np.random.default_rng(0))
    assert pts.shape == (512, 2)
    assert np.all(part.state_of(pts) == 12) and np.all(part.in_window(pts))
    # low-discrepancy: the sample mean is close to the polygon's centroid
    assert np.linalg.norm(pts.mean(axis=0) - part.centroids[12]) < 0.01
    with pytest.raises(ValueError, match="state"):
        qb.sample_state(part, 20, 4, np.random.default_rng(0))


def test_corner_samples_stay_in_their_state():
    part = qp.get("edc")
    for i in (0, 6, 12, 17):
        pts = qb.support_sample_points(part, i, 200, np.random.default_rng(i))
        assert pts.shape == (200, 2)
        assert np.all(part.state_of(pts) == i) and np.all(part.in_window(pts))
        d = np.min(np.linalg.norm(pts[:, None] - qb.corner_points(part.polygons[i])[None], axis=-1),
                   axis=1)
        assert np.all(d <= 0.1 + 1e-12)


def test_corner_points_of_a_square_and_an_arc_state():
    sq = qb.corner_points(box(0, 0, 1, 1))
    assert sorted(map(tuple, sq.round(9).tolist())) == [(0, 0), (0, 1), (1, 0), (1, 1)]
    # EDC state 7 (0.5 <= y < 1, left, near A and near B): a lens cut by two lines; its
    # corners are B, (0, 0.5) and the circles' crossing (-sqrt(3)/2, 1/2).
    c = qb.corner_points(qp.get("edc").polygons[6])
    # (the crossing is cut from the circles' chords: within their 4.7e-6 sagitta)
    assert len(c) == 3
    for p in ([0.0, 1.0], [0.0, 0.5], [-np.sqrt(3) / 2, 0.5]):
        assert np.min(np.linalg.norm(c - p, axis=1)) < 1e-5


def test_random_configurations_counts_match_the_exact_lookup():
    counts = qb.random_configurations("lr", 50_000, 0)
    # LR: D in the BC window; every one of the 8 (i, j, k) occurs, the total is the kept number
    assert counts.shape == (2, 2, 2) and (counts > 0).all() and 0 < counts.sum() <= 50_000
    # by the mirror symmetry the counts of mirrored triples agree up to sampling noise
    np.testing.assert_allclose(counts, counts[::-1, ::-1, ::-1], rtol=0.1)


def test_mirror_permutation_is_an_involution_matching_the_lookup():
    for name in ("edc", "fdc", "lr", "tpcc"):
        part = qp.get(name)
        s = qb.mirror_permutation(part)
        assert s is not None and np.array_equal(s[s], np.arange(part.n_states))
        pts = np.random.default_rng(0).uniform(-0.9, 0.9, (1000, 2)) + [0, 0.5]
        np.testing.assert_array_equal(s[part.state_of(pts)], part.state_of(pts * [-1, 1]))


def test_build_is_deterministic_symmetric_and_worker_independent():
    a = qb.build("fdc", 48, seed=3, support_samples=16, progress=False)
    b = qb.build("fdc", 48, seed=3, support_samples=16, workers=2, progress=False)
    np.testing.assert_array_equal(a.T, b.T)
    assert a.sha256 == b.sha256 == qc.checksum(a.T)
    s = qb.mirror_permutation("fdc")
    np.testing.assert_array_equal(a.T, a.T[np.ix_(s, s, s)])
    assert abs(a.T.sum() - 1) < 1e-12 and a.T.min() >= 0
    c = qb.build("fdc", 48, seed=4, support_samples=16, progress=False)
    assert not np.array_equal(a.T, c.T) and np.array_equal(a.support, c.support)


def test_unsymmetric_build_agrees_with_the_mirrored_one():
    a = qb.build("fdc", 256, seed=1, support_samples=0, symmetric=False, progress=False)
    s = qb.mirror_permutation("fdc")
    r = qb.compare(a, a.T[np.ix_(s, s, s)])
    assert r["support_equal"] and r["l1"] < 0.02


def test_build_rejects_bad_arguments():
    with pytest.raises(ValueError, match="samples"):
        qb.build("lr", 0, progress=False)
    with pytest.raises(ValueError, match="workers"):
        qb.build("lr", 4, workers=0, progress=False)
    with pytest.raises(ValueError, match="support_weight"):
        qb.build("lr", 4, support_weight=1.5, progress=False)
    with pytest.raises(ValueError, match="partition"):
        qb.build("nope", 4, progress=False)


# ------------------------------------------------------------------------------------------
# files


@pytest.fixture(scope="module")
def small_lr():
    return qb.build("lr", 32, seed=0, support_samples=8, progress=False)


def test_save_load_roundtrip(tmp_path, small_lr):
    path = qc.save(tmp_path / "lr.npz", small_lr)
    t = qc.load(path)
    np.testing.assert_array_equal(t.T, small_lr.T)
    assert t.partition == "lr" and t.window == qp.get("lr").window and t.samples_per_state == 32
    assert t.meta["support_samples_per_state"] == 8 and t.path == path


def _err(path_or_name, monkeypatch=None, tmp_path=None):
    with pytest.raises(qc.TensorFileError) as info:
        if monkeypatch is not None:
            monkeypatch.setenv(qc.ENV_VAR, str(tmp_path))
            qc.tensor(path_or_name)
        else:
            qc.load(path_or_name)
    msg = str(info.value)
    assert "qfg tensors build --partition" in msg
    return msg


def _rewrite(path, **changes):
    with np.load(path) as z:
        data = {k: z[k] for k in z.files}
    data.update(changes)
    np.savez(path, **data)


def test_missing_file(tmp_path, monkeypatch):
    msg = _err("lr", monkeypatch, tmp_path)
    assert str(tmp_path / "lr.npz") in msg and "not found" in msg


@pytest.mark.parametrize("damage", ["truncate", "garbage", "flip", "shape", "checksum", "window",
                                    "support", "partition", "missing"])
def test_damaged_file_gives_clear_error(tmp_path, monkeypatch, small_lr, damage):
    path = qc.save(tmp_path / "lr.npz", small_lr)
    raw = path.read_bytes()
    if damage == "truncate":
        path.write_bytes(raw[: len(raw) // 2])
    elif damage == "garbage":
        path.write_bytes(b"not a tensor file at all")
    elif damage == "flip":  # a corrupted byte inside the compressed T
        with zipfile.ZipFile(path) as z:
            info = z.getinfo("T.npy")
        pos = info.header_offset + 30 + len(info.filename) + len(info.extra) + 40
        path.write_bytes(raw[:pos] + bytes([raw[pos] ^ 0xFF]) + raw[pos + 1:])
    elif damage == "shape":
        T = np.full((3, 3, 3), 1 / 27)
        _rewrite(path, T=T, support=T > 0, sha256=np.asarray(qc.checksum(T)))
    elif damage == "checksum":
        T = small_lr.T.copy()
        T[0, 0, 0] += 1e-3
        T[0, 0, 1] -= 1e-3
        _rewrite(path, T=T)
    elif damage == "window":
        _rewrite(path, window=np.array([-2.0, 2.0, -2.0, 3.0]))
    elif damage == "support":
        _rewrite(path, support=~small_lr.support)
    elif damage == "partition":
        _rewrite(path, partition=np.asarray("fdc"))
    elif damage == "missing":
        with np.load(path) as z:
            data = {k: z[k] for k in z.files if k != "sha256"}
        np.savez(path, **data)
    msg = _err("lr", monkeypatch, tmp_path)
    assert str(path) in msg


def test_float32_table_with_matching_checksum_is_rejected(tmp_path, monkeypatch, small_lr):
    # issue 12 item 11: the checksum is of the float64 values, so a float32 copy whose checksum
    # was recomputed after conversion passed every other check.
    path = qc.save(tmp_path / "lr.npz", small_lr)
    T32 = small_lr.table.astype(np.float32)
    _rewrite(path, T=T32, sha256=np.asarray(qc.checksum(T32.astype(float))),
             support=T32 > 0)
    msg = _err("lr", monkeypatch, tmp_path)
    assert str(path) in msg and "float32" in msg and "float64" in msg


@pytest.mark.parametrize("content", [b"T = [[0.5, 0.5]]\n", b"", b"\x93NUMPY"])
def test_non_npz_file_is_named_as_such(tmp_path, content):
    # issue 12 item 11: a text file named .npz was reported as "contains pickled (object) data".
    path = tmp_path / "lr.npz"
    path.write_bytes(content)
    msg = _err(path)
    assert str(path) in msg and "not an npz archive" in msg and "pickle" not in msg


def test_tensor_is_usable_as_an_array(small_lr):
    t = small_lr
    a = np.asarray(t)
    assert a is t.table and t.T is t.table  # no copy; .T is the documented alias
    assert (t.shape, t.ndim, t.dtype) == (a.shape, 3, np.float64)
    c = np.array(t)  # np.array copies by default
    assert c is not t.table and np.array_equal(c, t.table)
    assert np.asarray(t, dtype=np.float32).dtype == np.float32
    assert np.asarray(t, copy=True) is not t.table
    with pytest.raises(ValueError, match="copy"):
        np.asarray(t, dtype=np.float32, copy=False)
    np.testing.assert_allclose(np.sum(t, axis=(0, 1)), t.table.sum(axis=(0, 1)))
    # the online functions take the tensor, the array or the alias alike
    v = np.ones(t.n_states)
    np.testing.assert_array_equal(qc.marginal(t, v, v).p, qc.marginal(a, v, v).p)
    # the constructor takes table= or its alias T=, once
    kw = {f: getattr(t, f) for f in ("partition", "support", "window", "samples_per_state", "seed",
                                     "quad_segs", "version", "sha256", "meta")}
    assert qc.CompositionTensor(T=t.table, **kw).table is t.table
    with pytest.raises(ValueError, match="table"):
        qc.CompositionTensor(table=t.table, T=t.table, **kw)


def test_tensor_env_override_and_cache(tmp_path, monkeypatch, small_lr):
    qc.save(tmp_path / "lr.npz", small_lr)
    monkeypatch.setenv(qc.ENV_VAR, str(tmp_path))
    assert qc.tensors_dir() == tmp_path
    t = qc.tensor("LR")
    assert qc.tensor("lr") is t
    np.testing.assert_array_equal(t.T, small_lr.T)
    assert not t.T.flags.writeable


def test_cli_build_info_compare(tmp_path, capsys):
    out = tmp_path / "t"
    assert cli_main(["tensors", "build", "--partition", "lr", "--samples", "16",
                     "--support-samples", "4", "--output", str(out), "--no-progress"]) == 0
    assert cli_main(["tensors", "build", "--partition", "lr", "--samples", "32", "--seed", "1",
                     "--output", str(tmp_path / "u"), "--no-progress"]) == 0
    assert cli_main(["tensors", "info", str(out / "lr.npz")]) == 0
    assert cli_main(["tensors", "compare", str(out / "lr.npz"), str(tmp_path / "u" / "lr.npz")]) == 0
    assert cli_main(["tensors", "check", "--file", str(out / "lr.npz"),
                     "--configurations", "20000"]) == 0
    text = capsys.readouterr().out
    assert "non-zero 8 of 8" in text and "L1 =" in text and "only in a: 0" in text
    assert "8 distinct triples seen" in text and "seen but infeasible in the tensor: 0" in text
    (tmp_path / "bad.npz").write_bytes(b"xx")
    assert cli_main(["tensors", "info", str(tmp_path / "bad.npz")]) == 2
    assert "qfg tensors build --partition bad" in capsys.readouterr().err
