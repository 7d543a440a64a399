"""The field view as a process beside a graph (``./run demo --view``), an observer at idle priority like the
recorder."""

from __future__ import annotations

import argparse
import subprocess
import sys
import threading
import time
from pathlib import Path

from erforce_interfaces.tools.processes import spawn_in_session


def start_field_view(args: argparse.Namespace, out: Path, field: str, team_ids) -> subprocess.Popen:
    """The field view beside a graph (``--view``), an observer at idle priority like the recorder; a thread
    prints its address once it serves."""
    cmd = [str(Path(sys.executable).with_name("field_view")), "--ros-args", "-p", f"port:={args.view_port}",
           "-p", f"field:={field}", "-p", f"team_robot_ids:=[{','.join(str(r) for r in team_ids)}]",
           "-p", f"foxglove_port:={args.foxglove_port}"]
    view = spawn_in_session(cmd, out / "view.log", idle=True)
    threading.Thread(target=_announce_view, args=(view, out / "view.log", args), daemon=True).start()
    return view


def _announce_view(view: subprocess.Popen, log: Path, args: argparse.Namespace) -> None:
    while view.poll() is None:
        if "field view at" in log.read_text(errors="replace"):
            print(f"field view: http://127.0.0.1:{args.view_port}/", flush=True)
            if args.foxglove_port:
                print(f"Foxglove: ws://127.0.0.1:{args.foxglove_port} (layout: "
                      f"{Path(__file__).resolve().parents[2] / 'config' / 'foxglove_layout.json'})", flush=True)
            return
        time.sleep(0.2)
    print(f"the field view did not start; see {log}", flush=True)
