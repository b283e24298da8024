"""UAI model format: round trip with the triplet sidecar, a hand-written file, malformed files."""

import json

import numpy as np
import pytest

from qfg.graph import QualitativeFactorGraph, full_map
from qfg.inference import (
    FactorModel,
    JunctionTree,
    exact_marginals,
    read_uai,
    read_uai_graph,
    write_uai,
)
from qfg.inference.uai import sidecar_path


def small_graph(seed=0, partition=None, m=3):
    rng = np.random.default_rng(seed)
    T = rng.random((m, m, m)) * (rng.random((m, m, m)) < 0.8) + 1e-3
    g = QualitativeFactorGraph(partition, tensor=T)
    for t in [(0, 1, 2), (1, 2, 3), (0, 1, 3), (2, 3, 4), (1, 2, 4), (7, 8, 9)]:
        g.add_triplet(t, rng.random(m) if rng.random() < 0.5 else None)
    g.add_triplet((0, 1, 2), rng.random(m))
    g.discover_compositions()
    return g


@pytest.mark.parametrize("seed", range(3))
def test_round_trip_is_exact(tmp_path, seed):
    g = small_graph(seed)
    path = tmp_path / "g.uai"
    write_uai(g, path)
    h = read_uai_graph(path)
    assert h.triplets == g.triplets and h.factors == g.factors and h.partition == g.partition
    np.testing.assert_array_equal(h.table, g.table)                 # 17 digits: bit-exact
    for p, q in zip(g.priors, h.priors, strict=True):
        assert (p is None) == (q is None)
        if p is not None:
            np.testing.assert_allclose(q, p, rtol=1e-15)
    np.testing.assert_allclose(np.asarray(exact_marginals(h)), np.asarray(exact_marginals(g)),
                               atol=1e-15)


def test_round_trip_keeps_the_partition_name(tmp_path):
    rng = np.random.default_rng(1)
    g = QualitativeFactorGraph("lr", tensor=rng.random((2, 2, 2)))
    g.add_triplet((0, 1, 2), [0.3, 0.7])
    write_uai(g, tmp_path / "lr.uai")
    assert read_uai_graph(tmp_path / "lr.uai").partition == "lr"
    assert read_uai(tmp_path / "lr.uai").partition == "lr"


def test_file_layout_follows_the_format(tmp_path):
    g = small_graph(2)
    write_uai(g, tmp_path / "g.uai")
    tok = (tmp_path / "g.uai").read_text().split()
    n, F = g.n_triplets, int(g.seen.sum()) + g.n_factors
    assert tok[0] == "MARKOV" and int(tok[1]) == n and tok[2:2 + n] == ["3"] * n
    assert int(tok[2 + n]) == F
    meta = json.loads(sidecar_path(tmp_path / "g.uai").read_text())
    assert [tuple(t) for t in meta["triplets"]] == g.triplets
    assert len(meta["factors"]) == F


HAND = """MARKOV
3
2 2 3
3
1 0
2 0 1
2 1 2

2
 0.436 0.564

4
 0.128 0.872
 0.920 0.080

6
 0.210 0.333 0.457
 0.811 0.000 0.189
"""


def test_reads_a_hand_written_file(tmp_path):
    """The example of the UAI competition's format page (variables of different sizes)."""
    path = tmp_path / "hand.uai"
    path.write_text(HAND)
    model = read_uai(path)
    assert model.cards == (2, 2, 3) and model.scopes == ((0,), (0, 1), (1, 2))
    a = np.array([0.436, 0.564])
    b = np.array([[0.128, 0.872], [0.920, 0.080]])
    c = np.array([[0.210, 0.333, 0.457], [0.811, 0.000, 0.189]])
    joint = a[:, None, None] * b[:, :, None] * c[None, :, :]     # last scope variable fastest
    joint /= joint.sum()
    P = JunctionTree(model).marginals()
    for v, card in enumerate(model.cards):
        expect = joint.sum(axis=tuple(x for x in range(3) if x != v))
        np.testing.assert_allclose(P[v, :card], expect, atol=1e-12)
    with pytest.raises(ValueError, match="sidecar"):
        read_uai_graph(path)                                       # no triplets: not a graph


@pytest.mark.parametrize("text, match", [
    ("", "ends before the header"),
    ("BAYESIAN 1 2 0", "MARKOV or BAYES"),
    ("MARKOV 2 2 2 1 2 0 1 3 0.1 0.2 0.3", "declares 3 entries"),
    ("MARKOV 1 2 1 1 5 2 0.1 0.2", "scope"),
    ("MARKOV 1 2 1 1 0 2 0.1 -0.2", "negative"),
    ("MARKOV 1 2 1 1 0 2 0.1 x", "non-numeric"),
    ("MARKOV 1 2 1 1 0 2 0.1", "ends before entry 1"),
    ("MARKOV 1 2 1 1 0 2 0.1 0.2 9", "unexpected"),
    ("MARKOV x", "integer"),
])
def test_malformed_files_name_the_file(tmp_path, text, match):
    path = tmp_path / "bad.uai"
    path.write_text(text)
    with pytest.raises(ValueError, match=match) as info:
        read_uai(path)
    assert "bad.uai" in str(info.value)


def test_generic_model_round_trip(tmp_path):
    rng = np.random.default_rng(4)
    model = FactorModel(cards=(2, 3, 2), scopes=[(0, 1), (2,), (1, 2, 0)],
                        tables=[rng.random((2, 3)), rng.random(2), rng.random((3, 2, 2))])
    write_uai(model, tmp_path / "m.uai", sidecar=False)
    back = read_uai(tmp_path / "m.uai")
    assert back.cards == model.cards and back.scopes == model.scopes
    for a, b in zip(model.tables, back.tables, strict=True):
        np.testing.assert_array_equal(a, b)


def test_full_map_round_trip_sizes(tmp_path):
    g = full_map(4, partition=None, tensor=np.ones((2, 2, 2)))
    write_uai(g, tmp_path / "f.uai")
    h = read_uai_graph(tmp_path / "f.uai")
    assert h.n_triplets == 24 and h.n_factors == 24 and h.factors == g.factors
