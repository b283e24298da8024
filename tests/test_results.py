"""The labelled result types: one indexing rule (a triplet or a variable index), KeyError when
absent, ``in`` consistent with indexing, pickling keeps the rule. The results index
(``docs/results.md``, :mod:`qfg.harness.results_doc`): each page's lead, rebuilt
deterministically, and the repository's copy up to date."""

import pickle

import numpy as np
import pytest

from qfg.inference import Assignment, Marginals, MissingKeyError

P = np.array([[0.9, 0.1], [0.5, 0.5], [0.2, 0.8]])
TRIPLETS = ((0, 1, 2), (1, 2, 3), (0, 2, 3))


def _marginals():
    return Marginals(TRIPLETS, "lr", P, "test")


def test_triplet_and_variable_index_give_the_same_row():
    r = _marginals()
    for v, t in enumerate(TRIPLETS):
        assert np.array_equal(r[t], P[v])
        assert np.array_equal(r[v], P[v])
        assert np.array_equal(r[np.int64(v)], P[v])
        assert np.array_equal(r[tuple(np.int32(x) for x in t)], P[v])
        assert t in r and v in r


@pytest.mark.parametrize("key", [(0, 1, 3), (2, 1, 0), 3, -1, 10**12])
def test_absent_keys_raise_key_error_naming_them(key):
    r = _marginals()
    with pytest.raises(KeyError) as exc:
        r[key]
    assert str(key if isinstance(key, tuple) else int(key)) in str(exc.value)
    assert key not in r
    # still a ValueError for callers of the older results
    assert isinstance(exc.value, ValueError) and isinstance(exc.value, MissingKeyError)


@pytest.mark.parametrize("key", [slice(0, 2), np.array([True, False, True]), [0, 1], (0, 1),
                                 (0, 1, 2, 3), True, 1.0, "0", (0.0, 1, 2)])
def test_array_style_keys_are_refused(key):
    r = _marginals()
    with pytest.raises((TypeError, KeyError), match="probabilities|not in"):
        r[key]
    assert key not in r


def test_array_work_goes_through_probabilities():
    r = _marginals()
    assert np.array_equal(r.probabilities[[0, 2]], P[[0, 2]])
    assert np.array_equal(np.asarray(r), P)


def test_pickled_marginals_keep_the_rule():
    r = pickle.loads(pickle.dumps(_marginals()))
    assert np.array_equal(r[(0, 2, 3)], P[2]) and np.array_equal(r[1], P[1])
    with pytest.raises(KeyError):
        r[(9, 9, 9)]


def test_assignment_follows_the_same_rule():
    a = Assignment(TRIPLETS, "lr", [[1, 0, 1], [0, 0, 1]], [0.6, 0.4], np.log([0.6, 0.4]))
    assert a[(1, 2, 3)].tolist() == [0, 0] and a[2].tolist() == [1, 1]
    assert (0, 2, 3) in a and 2 in a and 3 not in a and (3, 2, 1) not in a
    with pytest.raises(KeyError, match=r"\(3, 2, 1\)"):
        a[(3, 2, 1)]
    with pytest.raises(KeyError, match="variable: 5"):
        a[5]


# ------------------------------------------------------------ the results index (docs/results.md)
def test_results_index_takes_each_pages_lead_and_links_the_page(tmp_path):
    from qfg.harness import results_doc

    secs = tmp_path / "results"
    secs.mkdir()
    (secs / "propagation.md").write_text(
        "## Propagation\n\n    qfg experiment propagation\n\n| a | b |\n|---|---|\n| 1 | 2 |\n\n"
        "![f](../figures/propagation/x.png) [other](exact_vs_approx.md) [g](../joint.md)\n\n"
        "### Details\n\nnot in the index\n")
    (secs / "single_triplet.md").write_text(
        "## Single triplet\n\n```bash\n# a comment, not a heading\nqfg experiment single-triplet\n```\n\n"
        "### More\n\nnot either\n")
    doc = results_doc.write(tmp_path / "results.md", results_dir=secs)
    text = doc.read_text()
    # paper order, each page linked, its lead kept, its details left on the page
    assert text.index("## Single triplet") < text.index("## Propagation")
    assert "[results/propagation.md](results/propagation.md)" in text
    assert "| 1 | 2 |" in text and "# a comment, not a heading" in text
    assert "not in the index" not in text and "not either" not in text
    # links rebased from docs/results/ to docs/
    assert "](figures/propagation/x.png)" in text and "](results/exact_vs_approx.md)" in text
    assert "](joint.md)" in text
    # the same pages give the same document
    assert results_doc.build_text(results_doc.sections(secs)) == text


def test_the_repositorys_results_index_is_up_to_date():
    from pathlib import Path

    from qfg.harness import results_doc

    docs = Path(__file__).resolve().parents[1] / "docs"
    if not (docs / "results").is_dir():
        pytest.skip("not a checkout")
    built = results_doc.build_text(results_doc.sections(docs / "results"))
    assert (docs / "results.md").read_text() == built, (
        "docs/results.md is stale: run `qfg experiment all --doc-only`")
