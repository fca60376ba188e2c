"""`ves precompute --json` of a scene text, for the accuracy benches (bench/peak_error.py,
bench/felt_error.py): the scene written into a folder, the basis beside it (replaced), the
summary parsed; a failed run ends the bench with its last line."""
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VES = os.environ.get("VES", os.path.join(ROOT, "target", "release", "ves"))


def precompute(dirname, name, text):
    """Writes `text` as DIRNAME/NAME.toml, runs it into NAME.h5; returns (summary, basis path)."""
    path = os.path.join(dirname, name + ".toml")
    with open(path, "w") as f:
        f.write(text)
    out = os.path.join(dirname, name + ".h5")
    p = subprocess.run([VES, "precompute", path, "-o", out, "--json", "--force"], capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{name}: ves precompute failed: {p.stderr.strip().splitlines()[-1:]}")
    return json.loads(p.stdout.strip().splitlines()[-1]), out
