"""One vocabulary: ``method=`` chooses a variant everywhere, the string passed is the string
``Marginals.method`` reports and ``qfg mrclam --map`` accepts, and every keyword, value or alias
it replaced fails with an error naming its replacement and CHANGELOG.md."""

import inspect
import warnings

import numpy as np
import pytest

import qfg
from qfg import configurations, inference, propagation
from qfg.configurations import (
    configuration_marginals,
    infer_configurations,
    summarize_position,
)
from qfg.graph import QualitativeFactorGraph, full_map
from qfg.inference import Marginals, exact_marginals, loopy_bp
from qfg.propagation import compare_unseen, propagate

#: every public function that chooses a variant -> (its methods, default first)
VARIANTS = {
    propagate: ("best", "pooled"),
    exact_marginals: ("junction", "contract", "gtsam"),
    compare_unseen: ("junction", "contract", "gtsam"),
    infer_configurations: ("config-state", "config-metric"),
    configuration_marginals: ("config-state", "config-metric"),
    qfg.solve_triplet: ("full", "fast", "fast-paper", "baseline", "reference"),
    qfg.solve_triplets: ("full", "fast", "fast-paper", "baseline", "reference"),
}


def _graph():
    g = QualitativeFactorGraph("lr")
    for t, p in [((0, 1, 2), [0.9, 0.1]), ((1, 2, 3), None), ((0, 1, 3), [0.3, 0.7])]:
        g.add_triplet(t, p)
    g.discover_compositions()
    return g


@pytest.mark.parametrize("func", list(VARIANTS), ids=lambda f: f.__name__)
def test_the_variant_keyword_is_method_with_the_first_value_as_default(func):
    sig = inspect.signature(func)
    assert "method" in sig.parameters
    assert sig.parameters["method"].default == VARIANTS[func][0]
    for old in ("rule", "engine", "likelihood", "kind", "how", "mode"):
        assert old not in sig.parameters


def test_the_method_constants_list_the_same_values():
    assert propagation.PROPAGATION_METHODS == VARIANTS[propagate]
    assert inference.EXACT_METHODS == VARIANTS[exact_marginals]
    assert configurations.METHODS == VARIANTS[infer_configurations]


@pytest.mark.parametrize("method", VARIANTS[propagate])
def test_propagate_reports_the_method_it_was_given(method):
    assert propagate(_graph(), method=method).method == method


@pytest.mark.parametrize("method", VARIANTS[exact_marginals])
def test_exact_marginals_reports_the_method_it_was_given(method):
    assert exact_marginals(_graph(), method=method).method == method
    assert compare_unseen(_graph(), method=method)[0]["exact"] is not None


def test_loopy_bp_reports_loopy_bp():
    assert loopy_bp(_graph()).method == "loopy-bp"


def test_the_joint_map_reports_joint():
    from qfg import joint
    from qfg.simulation import random_trajectory_run

    run = random_trajectory_run(np.random.default_rng(4), n_landmarks=4, n_poses=10,
                                fov_deg=360.0)
    post = joint.solve(joint.simulated_measurements(run), joint.SolveParams(starts=1))
    res = joint.triplet_marginals(post, samples=100, seed=0)
    assert post.method == "joint" and res.method == "joint"
    assert res.states == qfg.partitions.get("edc").labels


def _edc_evidence():
    rng = np.random.default_rng(0)
    p = np.eye(20)[1] * 0.9 + 0.005
    s = summarize_position((rng.normal([0.5, 2.0], 0.2, (200, 2)), np.ones(200)), p, seed=1)
    return {"config-state": {(0, 1, 2): p}, "config-metric": {(0, 1, 2): s}}


@pytest.mark.parametrize("method", VARIANTS[configuration_marginals])
def test_configuration_marginals_report_the_method_they_were_given(method):
    ev = _edc_evidence()[method]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = configuration_marginals(ev, triplets=[(0, 1, 2)], method=method, n_particles=200)
        post = infer_configurations(ev, method=method, n_particles=200)
        again = post.marginals([(0, 1, 2)])
    assert r.method == method and post.method == method and again.method == method


def test_configuration_inference_draws_with_seed_0_by_default():
    ev = _edc_evidence()["config-state"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = configuration_marginals(ev, triplets=[(0, 1, 2), (1, 0, 2)], n_particles=200)
        b = configuration_marginals(ev, triplets=[(0, 1, 2), (1, 0, 2)], n_particles=200, seed=0)
    assert inspect.signature(infer_configurations).parameters["seed"].default == 0
    assert inspect.signature(configuration_marginals).parameters["seed"].default == 0
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_the_mrclam_cli_accepts_the_library_values():
    from qfg.harness.cli import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    mrclam = sub.choices["mrclam"]
    choices = next(a for a in mrclam._actions if a.dest == "map").choices
    want = {"joint", "pooled", "best", "seen", "config-state", "config-metric", "seen-config",
            "seen-prior"}
    assert set(choices) == want
    # the maps named after a library method are that method
    assert {*VARIANTS[propagate], *VARIANTS[configuration_marginals]} <= set(choices)


# ----------------------------------------------------------------------------- the old names
@pytest.mark.parametrize("call, new", [
    (lambda g: propagate(g, rule="best"), "method="),
    (lambda g: exact_marginals(g, engine="junction"), "method="),
    (lambda g: compare_unseen(g, engine="junction"), "method="),
    (lambda g: configuration_marginals({(0, 1, 2): np.full(20, 0.05)}, likelihood="state"),
     "method="),
    (lambda g: infer_configurations({(0, 1, 2): np.full(20, 0.05)}, likelihood="metric"),
     "method="),
], ids=["rule", "engine", "compare_unseen-engine", "likelihood", "infer-likelihood"])
def test_an_old_keyword_names_the_new_one(call, new):
    with pytest.raises(TypeError) as exc:
        call(_graph())
    msg = str(exc.value)
    assert "\n" not in msg and new in msg and "CHANGELOG.md" in msg


@pytest.mark.parametrize("call, new", [
    (lambda: propagate(_graph(), method="mean"), "'pooled'"),
    (lambda: configuration_marginals({(0, 1, 2): np.full(20, 0.05)}, method="state"),
     "'config-state'"),
    (lambda: infer_configurations({(0, 1, 2): np.full(20, 0.05)}, method="metric"),
     "'config-metric'"),
], ids=["mean", "state", "metric"])
def test_an_old_value_names_the_new_one(call, new):
    with pytest.raises(ValueError) as exc:
        call()
    msg = str(exc.value)
    assert "\n" not in msg and new in msg and "CHANGELOG.md" in msg


@pytest.mark.parametrize("module, name, new", [
    (propagation, "propagate_pooled", 'method="pooled"'),
    (propagation, "PropagationResult", "Marginals"),
    (propagation, "BPResult", "Marginals"),
    (propagation, "PROPAGATION_RULES", "PROPAGATION_METHODS"),
    (inference, "ENGINES", "EXACT_METHODS"),
    (configurations, "LIKELIHOODS", "METHODS"),
])
def test_a_removed_alias_names_its_replacement(module, name, new):
    with pytest.raises(AttributeError) as exc:
        getattr(module, name)
    msg = str(exc.value)
    assert "\n" not in msg and new in msg and "CHANGELOG.md" in msg
    assert name not in module.__all__ and name not in qfg.__all__


def test_marginals_marginals_is_removed_in_favour_of_probabilities():
    r = propagate(_graph())
    with pytest.raises(AttributeError, match=r"probabilities.*CHANGELOG\.md"):
        r.marginals  # noqa: B018


# ----------------------------------------------------------------------------- state names
def test_marginals_carry_and_print_the_partitions_state_names():
    r = exact_marginals(_graph())
    assert r.states == ("L", "R")
    assert "states=('L', 'R')" in repr(r)
    head = str(r).splitlines()[1].split()
    assert head == ["triplet", "L", "R"]
    edc = full_map(4, partition="edc", tensor=np.ones((20, 20, 20)))
    assert propagate(edc).states == qfg.partitions.get("edc").labels
    unlabelled = full_map(4, partition=None, tensor=np.ones((3, 3, 3)))
    assert exact_marginals(unlabelled).states == ("1", "2", "3")
    with pytest.raises(ValueError, match="states"):
        Marginals(((0, 1, 2),), "lr", [[0.5, 0.5]], "best", states=("L",))


def _public_callables():
    """Every public function and class of every library module (``qfg`` outside the harness),
    with the methods of the classes."""
    import importlib
    import pkgutil

    seen = set()
    for info in pkgutil.walk_packages(qfg.__path__, "qfg."):
        if info.name.startswith(("qfg.harness", "qfg.__main__")) or "._" in info.name:
            continue
        mod = importlib.import_module(info.name)
        for name, obj in vars(mod).items():
            if name.startswith("_") or getattr(obj, "__module__", "") != mod.__name__:
                continue
            if inspect.isfunction(obj) and obj not in seen:
                seen.add(obj)
                yield f"{mod.__name__}.{name}", obj
            elif inspect.isclass(obj) and obj not in seen:
                seen.add(obj)
                for m, f in vars(obj).items():
                    f = f.__func__ if isinstance(f, (classmethod, staticmethod)) else f
                    if (not m.startswith("_") or m == "__init__") and inspect.isfunction(f):
                        yield f"{mod.__name__}.{name}.{m}", f


#: seeds that are recorded data, not a draw: the seed a stored tensor was built with
NOT_A_DRAW = {"qfg.composition.store.CompositionTensor.__init__"}


def test_every_seed_defaults_to_0():
    # one seed default everywhere: the same call gives the same answer
    found, bad = 0, []
    for name, f in _public_callables():
        if name in NOT_A_DRAW:
            continue
        p = inspect.signature(f).parameters.get("seed")
        if p is None or p.default is inspect.Parameter.empty:
            continue
        found += 1
        if not (isinstance(p.default, int) and not isinstance(p.default, bool) and p.default == 0):
            bad.append(f"{name}: seed={p.default!r}")
    assert found >= 10, "the walk found too few seeded functions to mean anything"
    assert not bad, "seed defaults other than 0:\n" + "\n".join(bad)
