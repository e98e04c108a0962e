#!/usr/bin/env python3
"""Fail when a file of the repository cites a file that is not in the repository.

Usage: python .ci/check_references.py [--root DIR] [FILE ...]

Scans FILE ... (relative to the root; default: every file `git ls-files` lists, or, outside a
git checkout, every file under the root except hidden and build directories), prints
`file:line: reference: problem` for each bad reference and exits 1 if there is one, else 0.
Binary files are skipped. Standard library only.

The rules, kept simple on purpose:

1. Paths. A token that starts with a top-level directory of the repository (docs/, rust/,
   python/, tests/, benches/, .ci/) or with ../, or that names a Markdown file
   (ends in .md), is a path. Surrounding punctuation is stripped and a #anchor split off. It
   resolves if it is a tracked file, or a directory holding one, relative to the repository
   root or to the citing file's directory; a `*` matches like a shell glob.
2. Headings. `file.md#anchor` needs a heading of file.md whose GitHub anchor is `anchor`
   (lower case, punctuation dropped, spaces to hyphens). A heading quoted right after a
   Markdown path, as in `docs/algorithms.md, "Doubling"`, needs a heading with that text.
3. Numbered sections. The section sign § always fails: the project's docs are cited by
   heading (rule 2) and textbooks by equation number, so a § can only point into notes that
   are not part of the repository, which users never see.

Not references: URLs (`scheme://...`), dotted names (kfast.models, np.linalg), absolute paths
(/tmp/x), a path that continues a longer word (src/rust/x), patterns with a <placeholder>
(tests/test_<family>.py, "<heading>"), and any line containing
`check-references: ignore`. This script and its test, tests/test_repository.py, are not
scanned (the one names what it looks for, the other plants bad references).

PLANNED lists files a move in progress will create, each with the current file its content is
in now: a reference to a planned file passes while that current file exists. When this script
checks its own repository, an entry whose planned file exists, or whose current file is gone,
fails the check until it is deleted or fixed.
"""

from __future__ import annotations

import argparse
import fnmatch
import os
import re
import subprocess
import sys
from pathlib import Path, PurePosixPath

SELF = ".ci/check_references.py"
# Not scanned: this script names what it looks for, and its test plants bad references.
EXEMPT = {SELF, "tests/test_repository.py"}
IGNORE_MARK = "check-references: ignore"

# Files a move in progress will create (planned file -> where its content is now).
PLANNED: dict[str, str] = {}

ROOTS = ("docs", "rust", "python", "tests", "benches", ".ci")
_CHARS = r"[\w.\-/*]"
PATH_RE = re.compile(
    r"(?<![\w./\-])("
    r"(?:\.\./)+" + _CHARS + r"*"
    r"|(?:" + "|".join(re.escape(r) for r in ROOTS) + r")/" + _CHARS + r"*"
    r"|" + _CHARS + r"+\.md\b"
    r")(#[\w\-]+)?"
)
QUOTED_HEADING_RE = re.compile(r"(?<![\w./\-])(" + _CHARS + r"+\.md)(?:#[\w\-]+)?,\s*\"([^\"]+)\"")
OUTSIDE_RE = re.compile(r"§")
URL_RE = re.compile(r"\b[a-z][a-z0-9+.\-]*://\S*")
HEADING_RE = re.compile(r"^ {0,3}#{1,6}\s+(.*?)\s*#*\s*$")
SKIP_DIRS = {"target", "dist", "build", "__pycache__", "node_modules"}


def git(root: Path, *args: str) -> str:
    return subprocess.run(["git", *args], cwd=root, capture_output=True, check=True).stdout.decode()


def tracked_files(root: Path) -> list[str]:
    """`git ls-files` when root is the top of a git checkout, else a plain walk."""
    try:
        if Path(git(root, "rev-parse", "--show-toplevel").strip()).resolve() != root:
            raise ValueError("not the top of a checkout")
        return [f for f in git(root, "ls-files", "-z").split("\0") if f]
    except (OSError, ValueError, subprocess.CalledProcessError):
        files = []
        for dirpath, dirnames, filenames in os.walk(root):
            dirnames[:] = [
                d for d in dirnames
                if d not in SKIP_DIRS and not d.endswith(".egg-info") and (d == ".ci" or not d.startswith("."))
            ]
            for name in filenames:
                files.append(Path(dirpath, name).relative_to(root).as_posix())
        return sorted(files)


def read_text(path: Path):
    """The file's lines, or None for a binary (or unreadable) file."""
    try:
        data = path.read_bytes()
    except OSError:
        return None
    if b"\0" in data:
        return None
    try:
        return data.decode("utf-8").splitlines()
    except UnicodeDecodeError:
        return None


def slug(heading: str) -> str:
    """GitHub's anchor of a heading."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


class Repository:
    def __init__(self, root: Path, files: list[str]):
        self.root = root
        self.files = set(files)
        self.dirs = {str(p) for f in files for p in PurePosixPath(f).parents if str(p) != "."}
        self._headings: dict[str, list[str]] = {}

    def exists(self, path: str) -> bool:
        if any(c in path for c in "*?["):
            return any(fnmatch.fnmatch(f, path) for f in self.files)
        return path in self.files or path in self.dirs

    def planned(self, path: str) -> bool:
        current = PLANNED.get(path)
        if current is not None:
            return current in self.files
        prefix = path.rstrip("/") + "/"
        return any(p.startswith(prefix) and c in self.files for p, c in PLANNED.items())

    def headings(self, path: str) -> list[str]:
        if path not in self._headings:
            lines = read_text(self.root / path) or []
            found, fence = [], False
            for line in lines:
                if line.lstrip().startswith("```"):
                    fence = not fence
                m = HEADING_RE.match(line)
                if m and not fence:
                    found.append(m.group(1))
            self._headings[path] = found
        return self._headings[path]

    def anchors(self, path: str) -> set[str]:
        """Anchors as GitHub numbers them: a repeated slug gets -1, -2, ..."""
        seen: dict[str, int] = {}
        out = set()
        for h in self.headings(path):
            s = slug(h)
            out.add(s if s not in seen else f"{s}-{seen[s]}")
            seen[s] = seen.get(s, 0) + 1
        return out

    def resolve(self, ref: str, citing: str):
        """The repository path `ref` names, relative to the root or to `citing`'s directory,
        or None."""
        for candidate in (ref, str(PurePosixPath(citing).parent / ref)):
            path = os.path.normpath(candidate).replace(os.sep, "/")
            if not path.startswith("..") and (self.exists(path) or self.planned(path)):
                return path
        return None


def problems_in_line(repo: Repository, citing: str, line: str):
    """(reference, problem) pairs of one line."""
    if IGNORE_MARK in line:
        return
    text = URL_RE.sub(" ", line)
    outside = [m.span() for m in OUTSIDE_RE.finditer(text)]
    for start, end in outside:
        yield text[start:end], "cites a numbered section of notes outside the repository (cite the textbook or a docs/ heading instead)"
    for m in PATH_RE.finditer(text):
        if any(start < m.end() and m.start() < end for start, end in outside):
            continue  # reported above
        if text[m.end() : m.end() + 1] == "<":
            continue  # a pattern such as tests/test_<family>.py
        ref, anchor = m.group(1).strip("*").rstrip(".-"), m.group(2)
        if not ref or ref in ("..", "../"):
            continue
        target = repo.resolve(ref, citing)
        if target is None:
            yield ref, "no such file in the repository"
        elif anchor and target.endswith(".md") and repo.exists(target):
            if anchor[1:] not in repo.anchors(target):
                yield ref + anchor, f"{target} has no heading with this anchor"
    for m in QUOTED_HEADING_RE.finditer(text):
        target = repo.resolve(m.group(1), citing)
        wanted = m.group(2).strip().lower()
        if wanted.startswith("<"):
            continue  # a pattern: "<heading>"
        if target and repo.exists(target) and wanted not in (h.lower() for h in repo.headings(target)):
            yield f'{m.group(1)}, "{m.group(2)}"', f"{target} has no heading with this text"


def check(repo: Repository, files: list[str]) -> list[str]:
    report = []
    for citing in files:
        if citing in EXEMPT:
            continue
        lines = read_text(repo.root / citing)
        for number, line in enumerate(lines or [], start=1):
            for ref, problem in problems_in_line(repo, citing, line):
                report.append(f"{citing}:{number}: {ref}: {problem}")
    for planned, current in PLANNED.items() if SELF in repo.files else ():
        if planned in repo.files:
            report.append(f"{SELF}: PLANNED: {planned} exists now: delete its entry")
        elif current not in repo.files:
            report.append(f"{SELF}: PLANNED: {planned}: its current file {current} is gone: fix the entry")
    return report


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=Path(__file__).resolve().parent.parent)
    parser.add_argument("files", nargs="*", help="files to scan (default: all tracked files)")
    args = parser.parse_args(argv)
    root = args.root.resolve()
    tracked = tracked_files(root)
    repo = Repository(root, tracked)
    report = check(repo, args.files or tracked)
    for entry in report:
        print(entry)
    if report:
        print(f"{len(report)} bad reference(s): cite files of the repository only", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
