"""The licence files the wheel carries: pyproject's ``license-files`` exist, and DATA-LICENSE names every kind
of CMU-derived file the package ships, CMU's terms and acknowledgement, and LaFAN1's licence.

Checked from the source tree without building (``pip wheel --no-deps .`` puts the ``license-files`` under
``*.dist-info/licenses/``; a build takes too long for the fast suite).
"""
from __future__ import annotations

import fnmatch
import os
import tomllib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ACKNOWLEDGEMENT = ("The data used in this project was obtained from mocap.cs.cmu.edu. "
                   "The database was created with funding from NSF EIA-0196217.")


def _pyproject() -> dict:
    with open(os.path.join(ROOT, "pyproject.toml"), "rb") as f:
        return tomllib.load(f)


def _read(name: str) -> str:
    with open(os.path.join(ROOT, name), encoding="utf-8") as f:
        return f.read()


def test_license_files_listed_and_present():
    project = _pyproject()["project"]
    files = project["license-files"]
    assert {"LICENSE", "DATA-LICENSE"} <= set(files)
    for name in files:
        assert os.path.isfile(os.path.join(ROOT, name)), name
    assert project["license"] == "Apache-2.0"
    text = _read("LICENSE")
    assert "Apache License" in text and "Version 2.0, January 2004" in text and "END OF TERMS AND CONDITIONS" in text


def test_data_license_covers_what_ships():
    text = _read("DATA-LICENSE")
    assert ACKNOWLEDGEMENT in " ".join(text.split())
    assert "may not be resold" in text and "CC BY-NC-ND" in text and "Apache" in text
    data_globs = [g for g in _pyproject()["tool"]["setuptools"]["package-data"]["inbetween_jax"]
                  if not g.endswith(".md")]
    for glob in data_globs:                               # every shipped data pattern is named
        assert any(fnmatch.fnmatch(w, f"inbetween_jax/{glob}") for w in text.split()), glob


def test_readme_points_to_data_license():
    readme = _read("README.md")
    assert "free for all uses" not in readme
    assert "DATA-LICENSE" in readme
