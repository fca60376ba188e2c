"""``ves.session``: a scripted device replayed as ``ves session`` replays it."""

from __future__ import annotations

import _thread
import json
import subprocess
import threading
import time

import numpy as np
import pytest

import ves


def tip_script(path, corner, lift=1e-3, hold=0.3):
    """Grab `corner`, raise it `lift` m over 0.1 s, hold until `hold` s."""
    x, y, z = corner
    rows = ["t,x,y,z,button", f"0,{x},{y},{z},1", f"0.1,{x},{y},{z + lift},1", f"{hold},{x},{y},{z + lift},1"]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_session_replays_a_script_as_the_cli_does(cli, cantilever, tmp_path):
    corner = cantilever.nodes[np.argmax(cantilever.nodes[:, 0] + cantilever.nodes[:, 1] + cantilever.nodes[:, 2])]
    script = tip_script(tmp_path / "pull.csv", corner)
    stats = ves.session(cantilever, [script], stiffness=2e4, max_force=50.0)
    run = subprocess.run(
        [
            str(cli), "session", str(cantilever.path), "--device", f"script:{script}",
            "--stiffness", "20000", "--max-force", "50", "--no-realtime", "--json",
        ],
        capture_output=True, text=True, check=True,
    )
    expected = json.loads(run.stdout.strip().splitlines()[-1])
    assert stats["steps"] == expected["steps"] == 300
    np.testing.assert_allclose(stats["final_forces_n"], expected["final_forces_n"], rtol=1e-12, atol=0)
    np.testing.assert_allclose(stats["peak_force_n"], expected["peak_force_n"], rtol=1e-12)
    assert stats["bytes_loaded"] == expected["bytes_loaded"]
    # Pulled up by the hand: the device is pulled back down, about k × lift.
    fz = stats["final_forces_n"][0][2]
    assert -2e4 * 1e-3 < fz < -0.9 * 2e4 * 1e-3
    # What the clamped root carries: the CLI's, and pulling the part back down.
    (root,) = stats["support_reactions"]
    np.testing.assert_allclose(root["final_force_n"], expected["support_reactions"][0]["final_force_n"], rtol=1e-9)
    assert root["final_force_n"][2] < 0 < -fz
    assert stats["realtime"] is None


def test_ctrl_c_ends_a_session_early(cantilever, tmp_path):
    corner = cantilever.nodes[0]
    script = tip_script(tmp_path / "long.csv", corner, hold=30.0)
    timer = threading.Timer(0.5, _thread.interrupt_main)
    timer.start()
    t = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        ves.session(cantilever, [script])
    timer.cancel()
    assert time.monotonic() - t < 5.0


@pytest.mark.parametrize(
    "kwargs, kind",
    [
        ({"rate": 0.0}, "rate"),
        ({"stiffness": -1.0}, "stiffness"),
        ({"duration": float("inf")}, "duration"),
        ({"strain_policy": "panic"}, "strain_policy"),
        ({"modes": 0}, "modes"),
    ],
)
def test_bad_session_settings_are_value_errors(cantilever, tmp_path, kwargs, kind):
    script = tip_script(tmp_path / "s.csv", cantilever.nodes[0], hold=0.15)
    with pytest.raises(ValueError, match=kind):
        ves.session(cantilever, [script], **kwargs)
    with pytest.raises(ves.BasisError, match="rib1"):
        ves.session(cantilever, [script], space="rib1")


def test_bad_device_scripts_are_value_errors(cantilever, tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("0,1,2\n")
    with pytest.raises(ValueError, match="bad.csv"):
        ves.session(cantilever, [bad])
    with pytest.raises(ValueError, match="missing.csv"):
        ves.session(cantilever, [tmp_path / "missing.csv"])
    with pytest.raises(ValueError):
        ves.session(cantilever, [])
