"""UAI model format: round trip with the triplet sidecar, a hand-written file, malformed files;
evidence (against brute force, both .evid layouts), the PR/MAR/MAP tasks and their result files
on public UAI 2014 instances (tests/data/uai) against the competition's references and GTSAM,
the query interface and the ``qfg uai`` command."""

import itertools
import json
import math
import os
from pathlib import Path

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
    g.add_triplet((0, 1, 2), rng.random(m), replace=True)      # seen, whatever the loop drew
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
            np.testing.assert_array_equal(q, p)                     # bit for bit (issue 19)
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


# ------------------------------------------------------------------ issue 19: the reader
def _write_graph(tmp_path, meta_edit):
    g = small_graph(0)
    path = tmp_path / "g.uai"
    write_uai(g, path)
    meta = json.loads(sidecar_path(path).read_text())
    meta_edit(meta)
    sidecar_path(path).write_text(json.dumps(meta))
    return path


@pytest.mark.parametrize("edit, match", [
    (lambda m: m.update(triplets=5), "'triplets' must be a list"),
    (lambda m: m.update(triplets=[[0, 1]] * 6), "'triplets' must be a list"),
    (lambda m: m.update(factors="x"), "'factors' must be a list"),
    (lambda m: m.update(factors=[7] * len(m["factors"])), "'factors' must be a list"),
    (lambda m: m["factors"][-1].update(composition=[0, 1, 2, 99]), "composition"),
    (lambda m: m["factors"][-1].update(composition="abcd"), "composition must be"),
    (lambda m: m.update(partition=7), "'partition' must be one of"),
    (lambda m: m.update(partition="/etc/passwd"), "'partition' must be one of"),
])
def test_bad_sidecars_are_value_errors_naming_the_file(tmp_path, edit, match):
    """Issue 19: TypeError for a wrong type, 'tuple.index(x): x not in tuple' without the file,
    any partition accepted."""
    path = _write_graph(tmp_path, edit)
    with pytest.raises(ValueError, match=match) as info:
        read_uai_graph(path)
    assert "g.uai" in str(info.value)


def test_huge_cardinalities_do_not_wrap(tmp_path):
    """2^32 x 2^32 entries wrapped to 0 in int64 and a 0-entry table passed the size check."""
    path = tmp_path / "big.uai"
    path.write_text(f"MARKOV 2 {2**32} {2**32} 1 2 0 1 0")
    with pytest.raises(ValueError, match="declares 0 entries"):
        read_uai(path)


@pytest.mark.parametrize("token", ["1_0", "+2", "0x2", "2.0"])
def test_integers_are_plain_digits(tmp_path, token):
    path = tmp_path / "t.uai"
    path.write_text(f"MARKOV 1 {token} 1 1 0 2 0.5 0.5")
    with pytest.raises(ValueError, match="integer"):
        read_uai(path)


def test_factor_model_repr_is_short():
    g = full_map(6, partition=None, tensor=np.ones((20, 20, 20)))
    r = repr(FactorModel.from_graph(g))
    assert len(r) < 200 and "n=120" in r and "factors=360" in r


# ------------------------------------------------------------------ evidence
from qfg.inference import MemoryBudgetError, query, read_evid, solve_task  # noqa: E402
from qfg.inference.tasks import write_result  # noqa: E402


def random_model(rng, n=5, max_card=3, n_f=5):
    cards = [int(c) for c in rng.integers(2, max_card + 1, size=n)]
    scopes, tables = [], []
    for _ in range(n_f):
        k = int(rng.integers(1, 4))
        s = tuple(int(v) for v in rng.choice(n, size=k, replace=False))
        scopes.append(s)
        tables.append(rng.random([cards[v] for v in s]) * (rng.random([cards[v] for v in s]) < 0.9))
    return FactorModel(cards, scopes, tables)


def brute_joint(model):
    """The unnormalized joint over every assignment, by enumeration."""
    X = np.array(list(itertools.product(*[range(c) for c in model.cards])), dtype=np.intp)
    with np.errstate(divide="ignore"):
        return X, np.exp(model.log_value(X))


@pytest.mark.parametrize("seed", range(12))
def test_evidence_against_brute_force(seed):
    rng = np.random.default_rng(seed)
    model = random_model(rng)
    X, w = brute_joint(model)
    obs = rng.choice(model.n, size=int(rng.integers(1, 3)), replace=False)
    ev = {int(v): int(rng.integers(model.cards[v])) for v in obs}
    keep = np.all([X[:, v] == x for v, x in ev.items()], axis=0)
    Z = w[keep].sum()
    if not Z > 0:
        with pytest.raises(ValueError, match="no mass"):
            JunctionTree(model, evidence=ev).marginals()
        return
    jt = JunctionTree(model, evidence=ev)
    P, logz, _ = jt.calibrate()
    assert logz == pytest.approx(math.log(Z), rel=1e-12, abs=1e-12)
    for v, c in enumerate(model.cards):
        expect = np.bincount(X[keep, v], weights=w[keep], minlength=c) / Z
        np.testing.assert_allclose(P[v, :c], expect, atol=1e-12)
    # MAP given the evidence: the brute-force best value (ties: any argmax)
    x, lp = jt.map_assignment()
    assert all(x[v] == s for v, s in ev.items())
    assert lp == pytest.approx(math.log(w[keep].max() / Z), abs=1e-9)
    # the triplet-free query: labelled by variable
    q = query(model, [int(obs[0])], evidence=ev)
    assert list(q) == [int(obs[0])] and q[int(obs[0])][ev[int(obs[0])]] == 1.0


def test_evidence_cuts_the_graph():
    """A chain x0 - x1 - x2: observing x1 leaves two independent parts (no clique over all)."""
    T = np.array([[0.9, 0.1], [0.2, 0.8]])
    model = FactorModel([2, 2, 2], [(0, 1), (1, 2)], [T, T])
    jt = JunctionTree(model, evidence={1: 0})
    assert jt.estimate.width == 1
    np.testing.assert_allclose(jt.marginals()[[0, 2]], [[0.9 / 1.1, 0.2 / 1.1], [0.9, 0.1]])


@pytest.mark.parametrize("text", [
    "2 0 1 3 0",                 # UAI 2014: one line
    "2\n0 1\n3 0\n",             # pairs per line
    "1\n2 0 1 3 0\n",            # older: one sample
    "1\n2\n0 1\n3 0",
])
def test_both_evidence_layouts(tmp_path, text):
    path = tmp_path / "m.uai.evid"
    path.write_text(text)
    assert read_evid(path) == {0: 1, 3: 0}


@pytest.mark.parametrize("text, match", [
    ("2 0 1 3", "fit neither layout"),
    ("1 0 1_0", "not a non-negative integer"),
    ("2 0 1 0 0", "observed twice"),
    ("x", "not a non-negative integer"),
])
def test_bad_evidence_files(tmp_path, text, match):
    path = tmp_path / "bad.evid"
    path.write_text(text)
    with pytest.raises(ValueError, match=match) as info:
        read_evid(path)
    assert "bad.evid" in str(info.value)


def test_evidence_is_checked_against_the_model():
    model = FactorModel([2, 3], [(0, 1)], [np.ones((2, 3))])
    with pytest.raises(KeyError, match="evidence"):
        JunctionTree(model, evidence={5: 0})
    with pytest.raises(ValueError, match="outside"):
        JunctionTree(model, evidence={1: 3})
    assert read_evid_empty(model)


def read_evid_empty(model):
    return JunctionTree(model, evidence={}).evidence == {}


# ------------------------------------------------------------------ shipped public instances
DATA = Path(__file__).parent / "data" / "uai"


def _reference(path):
    from qfg.inference.tasks import read_result

    return read_result(path)


def _evid(name):
    p = DATA / f"{name}.uai.evid"
    return p if p.exists() else None


@pytest.mark.parametrize("name", ["Grids_12", "Promedus_24", "CSP_12"])
def test_pr_on_shipped_instances(tmp_path, name):
    r = solve_task(DATA / f"{name}.uai", "PR", evidence=_evid(name))
    ref = _reference(DATA / f"{name}.uai.PR")
    assert r.log10_z == pytest.approx(ref, abs=6e-5 * max(1.0, abs(ref)) / 10)  # 6 digits printed
    out = write_result(r, tmp_path / f"{name}.uai.PR")
    assert _reference(out) == pytest.approx(r.log10_z, rel=1e-14)


@pytest.mark.parametrize("name", ["Grids_12", "Promedus_24"])
def test_mar_on_shipped_instances(tmp_path, name):
    r = solve_task(DATA / f"{name}.uai", "MAR", evidence=_evid(name))
    ref = _reference(DATA / f"{name}.uai.MAR")
    assert len(r.marginals) == len(ref)
    err = max(float(np.abs(a - b).max()) for a, b in zip(r.marginals, ref, strict=True))
    assert err <= 5e-7                    # the references carry 6 significant digits
    back = _reference(write_result(r, tmp_path / f"{name}.uai.MAR"))
    for a, b in zip(back, r.marginals, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-14)


def _gtsam_map(model, ev):
    """GTSAM's max-product MPE of the clamped model (an independent engine)."""
    import gtsam

    from qfg.inference.evidence import clamp

    c = clamp(model, ev)
    graph = gtsam.DiscreteFactorGraph()
    for s, t in zip(c.scopes, c.tables, strict=True):
        graph.push_back(gtsam.DecisionTreeFactor([(v, c.cards[v]) for v in s],
                                                 np.asarray(t, dtype=float).ravel().tolist()))
    sol = graph.optimize()
    x = np.array([sol[v] if v not in ev else ev[v] for v in range(model.n)], dtype=np.intp)
    xc = x.copy()
    xc[list(ev)] = 0
    return x, float(c.log_value(xc)[0])


@pytest.mark.parametrize("name", ["Grids_12", "Promedus_24"])
def test_map_on_shipped_instances_against_gtsam(tmp_path, name):
    model = read_uai(DATA / f"{name}.uai")
    ev = read_evid(_evid(name)) if _evid(name) else {}
    r = solve_task(model, "MAP", evidence=ev)
    x = np.array(r.assignment)
    assert all(x[v] == s for v, s in ev.items())
    gx, glog = _gtsam_map(model, ev)
    from qfg.inference.evidence import clamp
    xc = x.copy()
    xc[list(ev)] = 0
    ours = float(clamp(model, ev).log_value(xc)[0])
    assert ours == pytest.approx(glog, abs=1e-9)          # the same best value
    text = write_result(r, tmp_path / "out.MAP").read_text().split()
    assert text[0] == "MAP" and int(text[1]) == model.n and [int(t) for t in text[2:]] == list(x)


def test_cli_writes_the_competition_result(tmp_path):
    from qfg.harness.cli import main

    out = tmp_path / "res" / "p.PR"
    rc = main(["uai", str(DATA / "Promedus_24.uai"), "--task", "PR", "--output", str(out)])
    assert rc == 0
    assert _reference(out) == pytest.approx(_reference(DATA / "Promedus_24.uai.PR"), abs=1e-5)
    # the default evidence is MODEL.evid; --no-evid drops it (a different Z)
    out2 = tmp_path / "noev.PR"
    assert main(["uai", str(DATA / "Promedus_24.uai"), "--task", "PR", "--no-evid",
                 "--output", str(out2)]) == 0
    assert abs(_reference(out2) - _reference(out)) > 1.0


def test_cli_refuses_over_the_memory_budget(tmp_path, capsys):
    from qfg.harness.cli import main

    rc = main(["uai", str(DATA / "Grids_12.uai"), "--task", "MAR", "--memory", "1K",
               "--output", str(tmp_path / "x.MAR")])
    assert rc != 0 and not (tmp_path / "x.MAR").exists()
    assert "memory budget" in capsys.readouterr().err


def test_query_on_a_graph_with_evidence():
    """Labelled by triplet; the copy tensor makes every triplet of a factor equal."""
    T = np.zeros((2, 2, 2))
    T[0, 0, 0] = T[1, 1, 1] = 1.0
    g = QualitativeFactorGraph(None, tensor=T)
    for t in [(0, 1, 2), (1, 2, 3), (0, 1, 3)]:
        g.add_triplet(t, [0.5, 0.5])
    g.discover_compositions()
    r = query(g, [(0, 1, 3), (1, 2, 3)], evidence={(0, 1, 2): 1})
    assert r.triplets == ((0, 1, 3), (1, 2, 3))
    np.testing.assert_allclose(r.probabilities, [[0, 1], [0, 1]])
    assert r.info["evidence"] == {(0, 1, 2): 1}
    assert r.info["log_partition"] == pytest.approx(math.log(0.125))
    with pytest.raises(KeyError):
        query(g, [(5, 6, 7)])
    with pytest.raises(KeyError, match="evidence"):
        query(g, None, evidence={(5, 6, 7): 0})
    # the graph's exact_marginals and map_assignment take the same evidence
    np.testing.assert_allclose(exact_marginals(g, evidence={(0, 1, 2): 1})[(0, 1, 3)], [0, 1])
    from qfg.inference import map_assignment
    assert map_assignment(g, evidence={(0, 1, 2): 1}).best == {t: 1 for t in g.triplets}


def test_tasks_refuse_before_work_over_budget():
    with pytest.raises(MemoryBudgetError, match="memory budget") as info:
        solve_task(DATA / "Grids_12.uai", "MAR", memory=1000)
    assert info.value.estimate > 1000 and info.value.budget == 1000


def test_read_result_names_a_file_that_is_not_one(tmp_path):
    from qfg.inference.tasks import read_result

    for text in ("MAP\n1 0\n", "MAR\n2 2 0.5 0.5\n", "", "PR\nx\n"):
        p = tmp_path / "bad.MAR"
        p.write_text(text)
        with pytest.raises(ValueError, match="bad.MAR"):
            read_result(p)


# ------------------------------------------------------------------ the qfg uai command: defects
def _cli(args, capsys):
    from qfg.harness.cli import main

    rc = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return rc, out, err


def _hand(tmp_path, text=HAND, name="hand.uai"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_cli_evidence_on_a_variable_the_model_lacks(tmp_path, capsys):
    """Was a KeyError traceback, exit 1."""
    model = _hand(tmp_path)
    evid = tmp_path / "e.evid"
    evid.write_text("2\n0 1\n5 1\n")
    rc, _, err = _cli(["uai", model, "--task", "PR", "--evid", evid,
                       "--output", tmp_path / "x.PR"], capsys)
    assert rc == 2 and err.count("\n") == 1
    assert f"{evid}, line 3" in err and "variable 5 is not in the model" in err
    assert "3 variables" in err and not (tmp_path / "x.PR").exists()
    # the library: a KeyError (as for a mapping) that is also a ValueError, naming the file
    with pytest.raises(KeyError, match="line 3"):
        solve_task(model, "PR", evidence=evid)
    with pytest.raises(ValueError, match="e.evid, line 1: state 7 of variable 2"):
        evid.write_text("1 2 7")
        query(model, None, evidence=evid)


def test_cli_zero_probability_evidence_is_said_of_the_evidence(tmp_path, capsys):
    """Was 'the priors contradict the tensor's support', qualitative-map wording."""
    model = _hand(tmp_path)
    evid = tmp_path / "z.evid"
    evid.write_text("2 1 1 2 1")           # phi(x1 = 1, x2 = 1) = 0.000
    for task in ("PR", "MAR", "MAP"):
        rc, _, err = _cli(["uai", model, "--task", task, "--evid", evid,
                           "--output", tmp_path / f"x.{task}"], capsys)
        assert rc == 2 and err.count("\n") == 1
        assert "z.evid" in err and "probability zero under the model" in err
        assert "prior" not in err and "tensor" not in err
    from qfg.inference import ZeroMassError

    with pytest.raises(ZeroMassError, match="probability zero"):
        solve_task(read_uai(model), "MAR", evidence={1: 1, 2: 1})
    # a plain model with no mass at all, no evidence: said of the model
    with pytest.raises(ZeroMassError, match="model: the product of the factors is 0") as info:
        solve_task(FactorModel([2], [(0,)], [np.zeros(2)]), "PR")
    assert "prior" not in str(info.value)


def test_cli_map_prints_the_assignment_probability(tmp_path, capsys):
    model = _hand(tmp_path)
    rc, out, _ = _cli(["uai", model, "--task", "MAP", "--output", tmp_path / "x.MAP"], capsys)
    r = solve_task(model, "MAP")
    assert rc == 0 and f"log10 p(MAP | e) = {r.log10_p:.6f}" in out
    X, w = brute_joint(read_uai(model))                 # the best joint by enumeration
    assert r.log10_p == pytest.approx(math.log10(w.max() / w.sum()), abs=1e-12)
    assert list(r.assignment) == X[np.argmax(w)].tolist() == [0, 1, 0]


def test_a_short_cardinality_line_is_reported_at_that_line(tmp_path, capsys):
    """Was 'factor 0 declares 2 entries, its scope needs 1', further down the file."""
    model = _hand(tmp_path, HAND.replace("2 2 3\n", "2 2\n"))
    with pytest.raises(ValueError, match=r"hand.uai, line 3: the cardinality line lists 2 "
                                         r"cardinalities, but line 2 declares 3 variables"):
        read_uai(model)
    rc, _, err = _cli(["uai", model, "--task", "PR", "--output", tmp_path / "x.PR"], capsys)
    assert rc == 2 and err.count("\n") == 1 and "line 3" in err
    long = _hand(tmp_path, HAND.replace("2 2 3\n", "2 2 3 2\n"), "long.uai")
    with pytest.raises(ValueError, match="long.uai, line 3: the cardinality line lists 4"):
        read_uai(long)
    # cardinalities wrapped over lines, or a file on one line, still read
    assert read_uai(_hand(tmp_path, HAND.replace("2 2 3\n", "2\n2 3\n"), "w.uai")).cards == (2, 2, 3)
    assert read_uai(_hand(tmp_path, " ".join(HAND.split()), "one.uai")).cards == (2, 2, 3)


@pytest.mark.parametrize("args, option", [
    (["--task", "XYZ"], "--task"),
    ([], "--task"),
    (["--task", "PR", "--memory"], "--memory"),
])
def test_cli_bad_option_is_one_line(tmp_path, capsys, args, option):
    """Was argparse's usage and message, four lines."""
    from qfg.harness.cli import main

    with pytest.raises(SystemExit) as info:
        main(["uai", str(_hand(tmp_path)), *args])
    err = capsys.readouterr().err
    assert info.value.code == 2 and err.count("\n") == 1
    assert err.startswith("qfg uai: error: ") and option in err
    if "XYZ" in args:
        assert all(t in err for t in TASKS)


from qfg.inference.tasks import TASKS  # noqa: E402


# ------------------------------------------------------------------ the result file
def _result_cases(tmp_path):
    (tmp_path / "file").write_text("x")
    return {"a folder": (tmp_path, "folder"),
            "under a file": (tmp_path / "file" / "r.PR", "is a file"),
            "on a full disk": (Path("/dev/full"), "No space left")}


@pytest.mark.parametrize("case", ["a folder", "under a file", "on a full disk"])
def test_cli_output_that_cannot_be_written(tmp_path, capsys, case):
    """Each was a traceback with exit 1."""
    out, reason = _result_cases(tmp_path)[case]
    if case == "on a full disk" and not out.exists():
        pytest.skip("no /dev/full")
    rc, _, err = _cli(["uai", _hand(tmp_path), "--task", "PR", "--output", out], capsys)
    assert rc == 2 and err.count("\n") == 1
    assert f"--output: cannot write the result {out}" in err and reason in err


def test_cli_default_output_in_a_deleted_directory(tmp_path, capsys, monkeypatch):
    if os.name != "posix":
        pytest.skip("a working directory cannot be removed while in use")
    model = _hand(tmp_path)
    gone = tmp_path / "gone"
    gone.mkdir()
    monkeypatch.chdir(gone)
    gone.rmdir()
    rc, _, err = _cli(["uai", model, "--task", "PR"], capsys)
    assert rc == 2 and err.count("\n") == 1
    assert "hand.uai.PR" in err and "current directory no longer exists" in err


def test_cli_rewrites_a_result_whole(tmp_path, capsys):
    out = tmp_path / "r.PR"
    out.write_text("PR\n-1.5\n")
    inode = out.stat().st_ino
    assert _cli(["uai", _hand(tmp_path), "--task", "PR", "--output", out], capsys)[0] == 0
    assert out.read_text().startswith("PR\n") and out.stat().st_ino != inode
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hand.uai", "r.PR"]


CHILD_FSIZE = """
import resource, sys
from qfg.harness.cli import main
resource.setrlimit(resource.RLIMIT_FSIZE, (20, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.skipif(os.name != "posix", reason="RLIMIT_FSIZE")
def test_cli_write_failing_after_20_bytes_keeps_the_old_result(tmp_path):
    """Was a 20-byte fragment where the old result had been, and an OSError traceback."""
    import subprocess
    import sys

    model = tmp_path / "m.uai"
    write_uai(random_model(np.random.default_rng(0), n=8, n_f=8), model, sidecar=False)
    out = tmp_path / "m.MAR"
    old = "MAR\n1 2 0.25 0.75\n" + "# an old result longer than twenty bytes\n"
    out.write_text(old)
    r = subprocess.run([sys.executable, "-c", CHILD_FSIZE, "uai", str(model), "--task", "MAR",
                        "--output", str(out)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and f"cannot write the result {out}" in r.stderr
    assert "File too large" in r.stderr and "Traceback" not in r.stderr
    assert out.read_text() == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.MAR", "m.uai"]
