"""Run the fuzz campaign and publish its figures in docs/reliability.md (issue #10).

    python tests/fuzz/report.py            # the fast profile (what CI runs), then the resource checks
    python tests/fuzz/report.py --long     # the long profile
    python tests/fuzz/report.py --no-write # print only

It runs ``pytest tests/fuzz`` with ``KFAST_FUZZ_LOG`` (every case's outcome as a JSON line),
counts the cases by outcome and failure kind and by entry point, runs the resource checks at
the published sizes (resources.py: 8 threads, a 10**7-step soak, 100 000 rounds of calls for
leaks) and replaces the part of docs/reliability.md between the ``report:begin`` and
``report:end`` markers.
"""

from __future__ import annotations

import argparse
import collections
import datetime
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
DOC = ROOT / "docs/reliability.md"
BEGIN, END = "<!-- report:begin -->", "<!-- report:end -->"

sys.path.insert(0, str(HERE))


def run_campaign(long: bool) -> tuple[list, float, str]:
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "cases.jsonl"
        env = dict(os.environ, KFAST_FUZZ_LOG=str(log))
        cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(HERE), "-k", "not test_fuzz_resources"]
        if long:
            cmd.append("--long")
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
        seconds = time.perf_counter() - t0
        summary = proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else proc.stderr[-500:]
        records = [json.loads(line) for line in log.read_text().splitlines()] if log.exists() else []
    return records, seconds, summary


def _table(header: list, rows: list) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(out)


def campaign_section(records: list, seconds: float, summary: str, profile: str) -> str:
    from fuzzcases import FAILURE_KINDS

    outcomes = collections.Counter(r["outcome"] for r in records)
    kinds = collections.Counter(r["kind"] for r in records if r["outcome"] == "failure")
    by_entry = collections.defaultdict(collections.Counter)
    for r in records:
        by_entry[r["entry"]][r["outcome"]] += 1
    lines = [
        f"Profile **{profile}**: {len(records)} cases in {seconds:.0f} s (pytest: {summary}).",
        "",
        _table(
            ["cases tried", "clear errors", "valid results", "failures"],
            [[len(records), outcomes["error"], outcomes["valid"], outcomes["failure"]]],
        ),
        "",
        "Failures by kind:",
        "",
        _table(["kind", "cases"], [[k, kinds[k]] for k in FAILURE_KINDS + tuple(sorted(set(kinds) - set(FAILURE_KINDS)))]),
        "",
        "By entry point:",
        "",
        _table(
            ["entry point", "cases", "clear errors", "valid", "failures"],
            [[e, sum(c.values()), c["error"], c["valid"], c["failure"]] for e, c in sorted(by_entry.items())],
        ),
    ]
    failing = [r for r in records if r["outcome"] == "failure"]
    if failing:
        groups = collections.OrderedDict()
        for r in failing:
            groups.setdefault((r["entry"], r["kind"], r["arg"]), []).append(r)
        lines += ["", "One reproducer per failing (entry point, kind, argument):", ""]
        for (entry, kind, arg), rs in groups.items():
            r = rs[0]
            lines.append(f"- `{entry}` {kind}, `{arg}` ({len(rs)} cases, e.g. {r['family']}: {r['variant'][:60]}): {r['detail'][:160]}")
            lines.append(f"  `python -c \"{r['repro']}\"`")
    return "\n".join(lines)


def resources_section(long: bool) -> str:
    import resources

    rows = []
    for name, fn in (
        ("threads: filter, smooth, filter_batch from 8 threads = serial", lambda: resources.threads_same_results(8, 2000, 3)),
        ("shared KalmanFilter.step from 8 threads", lambda: resources.shared_streaming_filter(8, 2000)),
        ("shared KalmanFilter update/predict from 8 threads", lambda: resources.shared_streaming_update_predict(8, 1000)),
        ("leak: RSS after 100 000 rounds of calls", lambda: resources.leak(100000)),
        ("soak: 10^7 steps (filter_batch) + 10^6 (streaming)", lambda: resources.soak(10**7)),
    ):
        t0 = time.perf_counter()
        try:
            figures, verdict = fn(), "pass"
        except AssertionError as exc:
            figures, verdict = {"error": str(exc)[:200]}, "FAIL"
        rows.append([name, verdict, ", ".join(f"{k} = {v}" for k, v in figures.items()), f"{time.perf_counter() - t0:.1f}"])
    return _table(["check", "result", "figures", "seconds"], rows)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--long", action="store_true", help="the long profile")
    parser.add_argument("--no-write", action="store_true", help="print the section instead of writing docs/reliability.md")
    parser.add_argument("--no-resources", action="store_true", help="skip the soak, threads and leak checks")
    args = parser.parse_args(argv)
    import kfast

    profile = "long" if args.long else "fast"
    records, seconds, summary = run_campaign(args.long)
    parts = [
        f"Generated by `python tests/fuzz/report.py{' --long' if args.long else ''}` on {datetime.date.today()} "
        f"(kfast {kfast.__version__}, {os.cpu_count()} cores).",
        "",
        "### Campaign",
        "",
        campaign_section(records, seconds, summary, profile),
    ]
    if not args.no_resources:
        parts += ["", "### Soak, threads, leaks", "", resources_section(args.long)]
    section = "\n".join(parts)
    if args.no_write:
        print(section)
        return 0
    text = DOC.read_text()
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    DOC.write_text(head + BEGIN + "\n" + section + "\n" + END + tail)
    print(f"wrote {DOC}: {len(records)} cases")
    return 0


if __name__ == "__main__":
    sys.exit(main())
