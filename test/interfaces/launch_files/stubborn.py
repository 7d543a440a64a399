"""Test helper: ignore the signals named in argv[1] (comma-separated, e.g. INT,TERM), start a
grandchild in the same process group, print both pids, then wait."""

import signal
import subprocess
import sys
import time

for name in sys.argv[1].split(","):
    if name != "NONE":
        signal.signal(getattr(signal, "SIG" + name), signal.SIG_IGN)
grandchild = subprocess.Popen(["sleep", "600"])
print(f"ready pid={subprocess.os.getpid()} grandchild={grandchild.pid}", flush=True)
try:
    time.sleep(600)
except KeyboardInterrupt:
    grandchild.terminate()
    grandchild.wait()
