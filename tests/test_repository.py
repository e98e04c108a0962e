"""The repository explains itself: every file it cites exists in it (.ci/check_references.py,
which `.ci/run` also runs), and the check does catch a bad reference."""

import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CHECK = ROOT / ".ci" / "check_references.py"


def run_check(*args):
    return subprocess.run([sys.executable, str(CHECK), *args], capture_output=True, text=True, timeout=120)


def test_every_reference_resolves():
    result = run_check("--root", str(ROOT))
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout == ""


def plant(root: Path, files: dict) -> list:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text), encoding="utf-8")
    return sorted(files)


def test_planted_bad_references_are_reported_by_file_and_line(tmp_path):
    files = plant(
        tmp_path,
        {
            "docs/guide.md": """\
                # Guide

                ## Doubling

                See [the notes](notes.md) and docs/guide.md#doubling.
                """,
            "docs/notes.md": "# Notes\n",
            "python/pkg/mod.py": """\
                '''Module.

                Cites docs/missing.md, "Doubling" of docs/guide.md, "Doubling".
                Cites docs/guide.md#no-such-heading and docs/guide.md, "No such heading".
                See ../notes/private.md, ../notes/cases/ and rust/src/gone.rs.
                '''
                import numpy as np  # np.linalg and kfast.models are module names, not files
                URL = "https://example.com/docs/missing.md"
                """,
            "tests/test_x.py": """\
                # docs/guide.md, tests/test_x.py and the directory python/pkg/ exist.
                # A pattern: tests/test_<family>.py.
                # The private notes, cited by section §3.
                """,
        },
    )
    result = run_check("--root", str(tmp_path), *files)
    assert result.returncode == 1
    reported = sorted(line.split(": ")[0] + ": " + line.split(": ")[1] for line in result.stdout.splitlines())
    assert reported == sorted(
        [
            "python/pkg/mod.py:3: docs/missing.md",
            "python/pkg/mod.py:4: docs/guide.md#no-such-heading",
            'python/pkg/mod.py:4: docs/guide.md, "No such heading"',
            "python/pkg/mod.py:5: ../notes/private.md",
            "python/pkg/mod.py:5: ../notes/cases/",
            "python/pkg/mod.py:5: rust/src/gone.rs",
            "tests/test_x.py:3: §",
        ]
    ), result.stdout


def test_clean_files_pass_and_ignore_mark_skips_a_line(tmp_path):
    files = plant(
        tmp_path,
        {
            "README.md": "# Read me\n\nSee docs/a.md, \"Section\" and [a](docs/a.md#section).\n",
            "docs/a.md": "# A\n\n## Section\n\nBack to [the README](../README.md).\n",
            "notes.py": "# cites ../notes/private.md on purpose  (check-references: ignore)\n",
        },
    )
    result = run_check("--root", str(tmp_path), *files)
    assert result.returncode == 0, result.stdout
