"""The experiment harness: everything above the library.

The runner (:mod:`qfg.harness.runner`), the studies and their registry
(:mod:`qfg.harness.studies`), the Dask executor (:mod:`qfg.harness.cluster`), the results
document (:mod:`qfg.harness.results_doc`), the demo, the figures (:mod:`qfg.harness.plotting`)
and the ``qfg`` command (:mod:`qfg.harness.cli`, one module per subcommand in
:mod:`qfg.harness.commands`). The harness imports the library; no library module imports the
harness (``tests/test_layers.py`` checks it). See ``docs/modules.md``.
"""
