"""Bundled data: example studies (``*.yaml``), models (``models/``) and tables (``tables/``).

The repository's ``studies/`` folder is a link to this one, so users edit the same
files the installed package reads (with :mod:`importlib.resources`).
"""
