"""The version lives in Cargo.toml only: pyproject.toml declares it dynamic (maturin fills it
in), the compiled module exports it, and the installed package's metadata agree."""

from __future__ import annotations

import importlib.metadata
import re
from pathlib import Path

import kfast

ROOT = next(p for p in Path(__file__).resolve().parents if (p / "Cargo.toml").exists())


def toml_table(name: str, path: Path) -> str:
    """The body of the table [name] of a TOML file (up to the next table)."""
    text = path.read_text(encoding="utf-8")
    match = re.search(rf"^\[{re.escape(name)}\]\s*$(.*?)(?=^\[|\Z)", text, re.M | re.S)
    assert match, f"{path.name} has no [{name}]"
    return match.group(1)


def cargo_version() -> str:
    match = re.search(r'^version\s*=\s*"([^"]+)"', toml_table("package", ROOT / "Cargo.toml"), re.M)
    assert match, "Cargo.toml's [package] has no version"
    return match.group(1)


def test_version_is_cargo_tomls_everywhere():
    version = cargo_version()
    assert re.fullmatch(r"\d+\.\d+\.\d+\S*", version)
    assert kfast.__version__ == version
    assert kfast._kfast.__version__ == version
    assert importlib.metadata.version("kfast") == version


def test_pyproject_does_not_repeat_it():
    project = toml_table("project", ROOT / "pyproject.toml")
    assert not re.search(r"^version\s*=", project, re.M)
    assert re.search(r'^dynamic\s*=\s*\[[^\]]*"version"', project, re.M)
