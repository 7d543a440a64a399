"""Run every benchmark in bench/ and write bench/RESULTS.md (``./run bench [--quick] [--only NAME]``).

Each bench module has ``run(quick) -> rows`` (name, value, unit, target, note). The results
file starts with the date and the machine; the README links to it. Speed figures are medians
measured in one run; the machine is shared, so compare ratios within a run rather than absolute
numbers across runs. With ``--only``
the other groups' rows of the existing file stay, and the header names the groups measured anew.
"""

from __future__ import annotations

import argparse
import importlib
import os
import platform
import sys
import time
from pathlib import Path

BENCH_DIR = Path(__file__).resolve().parent
sys.path.insert(0, str(BENCH_DIR))
from table import markdown_table  # noqa: E402 - bench/ is not a package

RESULTS = BENCH_DIR / "RESULTS.md"
MODULES = (
    ("ball model (Sec. 5)", "bench_ball_model"),
    ("chip tracking", "bench_chip"),
    ("chip detection's ceiling", "bench_chip_bound"),
    ("ball_predictor node", "bench_ball_predictor"),
    ("motion control (Sec. 4)", "bench_motion"),
    ("simulator (Sec. 2-3)", "bench_sim"),
    ("lockstep over DDS", "bench_lockstep"),
    ("field view", "bench_field_view"),
    ("self-healing graph", "bench_respawn"),
    ("floods", "bench_flood"),
    ("executors", "bench_executor"),
    ("SSL-Vision in", "bench_ssl_vision"),
    ("SSL logs", "bench_ssl_logs"),
)


def machine() -> str:
    cpu = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem_gib = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    return (f"{cpu}, {os.cpu_count()} cores, {mem_gib:.0f} GiB, {platform.system()} {platform.release()}, "
            f"Python {platform.python_version()}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs (for a smoke test)")
    parser.add_argument("--only", action="append", default=[], help="run only this module (repeatable)")
    parser.add_argument("--no-write", action="store_true", help="print only; leave bench/RESULTS.md alone")
    args = parser.parse_args(argv)
    lines = [
        f"Measured {time.strftime('%Y-%m-%d %H:%M %Z')} on {machine()}"
        + (" (quick mode)" if args.quick else "") + ".",
        "",
        "| group | benchmark | value | unit | target | note |",
        "|---|---|---|---|---|---|",
    ]
    failed = []
    groups = {}
    for group, module_name in MODULES:
        if args.only and module_name not in args.only:
            continue
        print(f"[bench] {module_name} ...", file=sys.stderr, flush=True)
        t0 = time.monotonic()
        try:
            rows = importlib.import_module(module_name).run(args.quick)
        except Exception as exc:  # a broken bench is reported, the others still run
            failed.append(module_name)
            lines.append(f"| {group} | {module_name} failed | — | — | — | {type(exc).__name__}: {exc} |")
            continue
        groups[group] = markdown_table(rows, group)[2:]
        lines += groups[group]
        print(f"[bench] {module_name}: {time.monotonic() - t0:.0f} s", file=sys.stderr, flush=True)
    text = "\n".join(lines) + "\n"
    print(text)
    if args.only and RESULTS.exists():
        text = merged(RESULTS.read_text(), lines[0], groups)
    if not args.no_write:
        RESULTS.write_text(text)
        print(f"[bench] wrote {RESULTS}", file=sys.stderr)
    return 1 if failed else 0


def merged(old: str, header: str, groups: dict[str, list[str]]) -> str:
    """``old`` (a RESULTS.md) with the rows of each group in ``groups`` put where that group's old rows were (at
    the end if it had none); the first line says when those groups were measured."""
    old_lines = old.splitlines()
    rows, placed = [], set()
    for line in old_lines:
        if not line.startswith("| ") or line.startswith("| group |"):
            continue
        group = line.split(" | ", 1)[0].removeprefix("| ")
        if group not in groups:
            rows.append(line)
        elif group not in placed:
            rows += groups[group]
            placed.add(group)
    rows += [line for group, lines in groups.items() if group not in placed for line in lines]
    first = (old_lines[0] if old_lines else "").split("; the other rows: ")[-1]  # the full run's line
    note = f"{header.rstrip('.')}: {', '.join(groups)} (--only); the other rows: {first}"
    return "\n".join([note, "", "| group | benchmark | value | unit | target | note |", "|---|---|---|---|---|---|",
                      *rows]) + "\n"


if __name__ == "__main__":
    sys.exit(main())
