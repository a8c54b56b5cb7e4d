"""Ctrl-C (SIGINT to the whole process group, as a terminal sends it) during long commands.

Each command must stop within seconds with exit status 130 and one line on stderr, leave no
worker process behind and nothing at (or next to) its destination.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from hlaid.clone import Clone

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="process groups and /proc are Linux-specific here")

HEIGHTS = [3000.0, 3000.0, 3000.0]


def _children(pid: int) -> list[int]:
    """PIDs whose parent is ``pid`` (from /proc)."""
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.append(int(d.name))
    return out


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def _interrupt(args: list[str], cwd: Path, *, after: str, workers: int = 0, delay: float = 0.5,
               timeout: float = 180.0, signum: int = signal.SIGINT, group: bool = True) -> tuple[int, float, list[str]]:
    """Run ``hlaid ARGS`` in a new session, send ``signum`` (SIGINT) to its group (``group``, as a
    terminal does; else to the command alone, as ``kill PID`` does) once stderr shows ``after`` (and
    ``workers`` child processes exist), and return (status, seconds to exit, stderr lines)."""
    env = {**os.environ, "HLAID_CACHE": str(cwd / "cache"), "PYTHONUNBUFFERED": "1"}
    p = subprocess.Popen([sys.executable, "-m", "hlaid", *args], cwd=cwd, env=env, start_new_session=True,
                         stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    seen = threading.Event()

    def read():
        for ln in p.stderr:
            lines.append(ln.rstrip("\n"))
            if after in ln:
                seen.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        t0 = time.monotonic()
        while not (seen.is_set() and len(_children(p.pid)) >= workers):
            assert p.poll() is None, f"finished before it could be interrupted: {lines[-5:]}"
            assert time.monotonic() - t0 < timeout, f"never got to {after!r}: {lines[-5:]}"
            time.sleep(0.1)
        time.sleep(delay)
        if group:
            os.killpg(p.pid, signum)
        else:
            os.kill(p.pid, signum)
        t1 = time.monotonic()
        try:
            rc = p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            pytest.fail(f"still running 20 s after signal {signum}; stderr ends {lines[-5:]}")
        elapsed = time.monotonic() - t1
        reader.join(5)
        t2 = time.monotonic()
        while _group_alive(p.pid) and time.monotonic() - t2 < 5:
            time.sleep(0.1)
        assert not _group_alive(p.pid), "processes of the command are left running"
        return rc, elapsed, lines
    finally:
        if _group_alive(p.pid):
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()


def _assert_interrupted(rc: int, elapsed: float, lines: list[str], command: str) -> None:
    assert rc == 130
    assert elapsed < 10
    assert lines[-1] == f"hlaid {command}: interrupted"
    assert not any("Traceback" in ln or "KeyboardInterrupt" in ln for ln in lines), lines


def _leftovers(folder: Path, name: str) -> list[str]:
    return [p.name for p in folder.iterdir() if p.name == name or p.name.startswith(f".{name}.")]


@pytest.fixture(scope="module")
def measurement(tmp_path_factory) -> Path:
    from hlaid.synthetic import load_simulation_config, measurement_from_config
    repo = Path(__file__).resolve().parents[1]
    cfg = load_simulation_config(repo / "configs" / "poc_3story.yaml")
    path = tmp_path_factory.mktemp("meas") / "meas.npz"
    measurement_from_config(cfg, base_dir=repo / "configs").save(path)
    return path


def test_ctrl_c_during_identify_path_training(measurement, tmp_path):
    """The default path-driven training: the story law runs in-process (compiled, parallel
    threads) while the kernel machines train on a worker pool."""
    out = tmp_path / "out"
    out.mkdir()
    rc, elapsed, lines = _interrupt(["identify", str(measurement), "-o", "out/c.json", "--no-cache"], tmp_path,
                                    after="[identify] hysteresis loop analysis", workers=2, delay=1.0)
    _assert_interrupted(rc, elapsed, lines, "identify")
    assert _leftovers(out, "c.json") == []


@pytest.mark.slow  # long: the default run stays under 10 minutes on 2 cores
def test_ctrl_c_during_ida(table1, tmp_path):
    Clone(building=table1.replace(height=HEIGHTS), provenance={"test": True}).save(tmp_path / "clone.json")
    rc, elapsed, lines = _interrupt(["ida", "clone.json", "--records", "builtin-suite", "--levels", "0.1:20:0.1",
                                     "--no-plots", "-o", "ida-out"], tmp_path, after="IDA of", delay=1.0)
    _assert_interrupted(rc, elapsed, lines, "ida")
    assert _leftovers(tmp_path, "ida-out") == []


@pytest.mark.slow  # the demo up to its identification; Ctrl-C in the pipeline is checked by the path training's test
def test_ctrl_c_during_demo(tmp_path):
    rc, elapsed, lines = _interrupt(["demo", "--out", "demo-out", "--cache", "cache"], tmp_path,
                                    after="hysteresis loop analysis and identification", delay=1.0)
    _assert_interrupted(rc, elapsed, lines, "demo")
    assert _leftovers(tmp_path, "demo-out") == []


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")  # the dropped one
def test_ctrl_c_dropped_in_a_finaliser_is_raised_again(capsys, monkeypatch):
    """SIGINT arriving while a ``__del__`` runs raises KeyboardInterrupt inside it, which Python
    drops ("Exception ignored in ..."); under the command line's handler the next progress
    message raises it again (``hlaid demo`` interrupted at such a moment used to finish and exit
    0), without Python's "Exception ignored" traceback on stderr. Clean-up code that runs while
    an exception is handled is not interrupted twice, and without the handler nothing changes."""
    from hlaid import _interrupt, _progress

    class Finaliser:
        def __del__(self):
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):  # the handler runs here, inside the finaliser
                pass

    monkeypatch.setattr(sys, "unraisablehook", sys.__unraisablehook__)  # Python's, not pytest's: it prints
    hook = sys.unraisablehook
    with _interrupt.sticky_sigint():
        obj = Finaliser()
        del obj  # KeyboardInterrupt raised and dropped inside __del__
        try:
            raise ValueError("clean-up in progress")
        except ValueError:
            _progress.info("clean-up")  # an exception is being handled: not raised here
        with pytest.raises(KeyboardInterrupt):
            _progress.info("next step")
        _progress.info("raised once")  # the flag is cleared
    assert "Exception ignored" not in capsys.readouterr().err
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler and sys.unraisablehook is hook
    _interrupt.check()  # outside the block: nothing pending
