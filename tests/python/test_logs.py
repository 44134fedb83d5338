"""A long command's log: with stderr a file (`fillgs train ... > train.log 2>&1`), progress
lines reach the file while the command runs, flushed, at the interval FILLGS_PROGRESS_SECONDS
sets (30 s by default); --quiet writes none. Run by CTest's python_module (same environment)."""
import os
import subprocess
import time

CLI = os.environ["FILLGS_BIN"]


def test_progress_lines_reach_a_log_while_the_command_runs(tmp_path):
    scene = str(tmp_path / "scene")
    subprocess.run([CLI, "synth", "--out", scene, "--frames", "3", "--width", "48", "--height", "36", "--quiet"], check=True)
    log = tmp_path / "train.log"
    env = dict(os.environ, FILLGS_PROGRESS_SECONDS="0.2")
    with open(log, "w") as f:
        p = subprocess.Popen([CLI, "train", "--images", scene, "--cameras", f"{scene}/transforms_train.json", "--out", str(tmp_path / "train"),
                              "--iterations", "100000"], stdout=f, stderr=subprocess.STDOUT, env=env)
    try:
        deadline, seen = time.time() + 60, ""
        while time.time() < deadline and p.poll() is None:
            seen = log.read_text()
            if seen.count("progress: training") >= 3:
                break
            time.sleep(0.2)
        assert p.poll() is None, "train ended before its log showed progress"
        lines = [line for line in seen.splitlines() if line.startswith("progress: training")]
        assert len(lines) >= 3, seen
        assert all("%" in line and " s" in line for line in lines), lines
    finally:
        p.kill()
        p.wait()
    with open(tmp_path / "quiet.log", "w") as f:
        subprocess.run([CLI, "train", "--images", scene, "--cameras", f"{scene}/transforms_train.json", "--out", str(tmp_path / "q"),
                        "--iterations", "50", "--quiet"], stdout=f, stderr=subprocess.STDOUT, env=env, check=True)
    assert "progress:" not in (tmp_path / "quiet.log").read_text()
