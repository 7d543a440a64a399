"""The one markdown table format of every benchmark in bench/ (rows: name, value, unit, target, note)."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable


def format_value(value) -> str:
    if isinstance(value, bool) or (not isinstance(value, int | float) and not hasattr(value, "__float__")):
        return str(value)
    if float(value).is_integer() and abs(value) < 1e15 and not isinstance(value, float):
        return str(int(value))
    return f"{float(value):.3g}" if abs(float(value)) >= 1e5 else f"{float(value):.4g}"


def markdown_table(rows: list[dict], group: str | None = None) -> list[str]:
    """Table lines; with ``group`` a first column names the bench (and a row's own group, if any)."""
    head = ["| benchmark | value | unit | target | note |", "|---|---|---|---|---|"]
    if group is not None:
        head = ["| group | benchmark | value | unit | target | note |", "|---|---|---|---|---|---|"]
    lines = []
    for r in rows:
        cells = [r["name"], format_value(r["value"]), r.get("unit", ""), r.get("target", ""), r.get("note", "")]
        if group is not None:
            cells.insert(0, group + (f" ({r['group']})" if r.get("group") else ""))
        lines.append("| " + " | ".join(str(c) for c in cells) + " |")
    return head + lines


def bench_main(run: Callable[[bool], list[dict]], description: str, argv: list[str] | None = None,
               quick_help: str = "shorter runs") -> int:
    """The command line of a bench module: ``[--quick]``, then the table and the total time."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--quick", action="store_true", help=quick_help)
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    print("\n".join(markdown_table(run(args.quick))))
    print(f"\n(total {time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit("bench/table.py is a helper; run bench/run_all.py or a bench_*.py module")
