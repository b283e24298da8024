"""Studies run by :mod:`qfg.runner`: one module each, exposing ``STUDY``.

Their presets (the parameters of ``--preset quick|paper``) are in the repository's
``experiments/<name>.toml``.
"""
