"""How fast a bad input is refused: wall time of ``hlaid ...`` exiting on bad configs, clones, files,
outputs, addresses and environment variables, against ``hlaid --help`` (the peer) in the same run.

Each case is run ``--repeat`` times as a fresh ``python -m hlaid ...`` process (the interpreter that
runs this script: set ``PYTHONPATH`` to time a source tree) in a scratch folder; the table gives the
exit status, the median and worst wall time, the ratio of the median to the peer's and the peak
resident memory of the process (Linux). The target is a refusal in under 0.5 s (``--limit``), i.e. before torch,
numba or scipy are imported; refusals that need the data (another building's stories or masses,
one record twice, a closed scheduler port, a config of 200 000 keys, a gzip bomb, a band above the
Nyquist frequency) in under 1 s (``--limit-data``).

    python scripts/bench_bad_input.py [--repeat 5] [--limit 0.5] [--limit-data 1.0]

Exit status 1 when a case does not exit with status 2 or a median is above its limit.
"""

from __future__ import annotations

import argparse
import gzip
import io
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

STORY = "{weight_kN: 171.85, k0: 1.94e4, alpha: 0.23, p: 2.5, dy: 7.0, delta_eta: 0.7}"
BOMB = ('a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n'
        "b: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a]\nc: &c [*b,*b,*b,*b,*b,*b,*b,*b,*b]\n")


def _clone(d: Path, name: str, change=None) -> str:
    from hlaid.clone import Clone
    from hlaid.model import Building
    b = Building(mass=[17.5, 17.5, 9.2], k0=[2e4, 1.8e4, 1.5e4], alpha=[0.2] * 3, p=[2.0] * 3, dy=[7.0] * 3,
                 delta_eta=[0.5] * 3, height=[3000.0] * 3)
    data = Clone(building=b).to_dict()
    if change:
        change(data)
    (d / name).write_text(json.dumps(data))
    return name


def _lying_npz(path: Path) -> None:
    with zipfile.ZipFile(path, "w") as z:
        for name, shape in (("dt", ()), ("ground_acc", (10**10,)), ("floor_acc", (50, 10**9))):
            head = io.BytesIO()
            np.lib.format.write_array_header_1_0(head, {"descr": "<f8", "fortran_order": False, "shape": shape})
            z.writestr(name + ".npy", head.getvalue() + (b"\0" * 8 if shape == () else b""))


def _measurement(path: Path, n_floors: int = 3, mass_factor: float = 1.0, seed: int = 0) -> str:
    """A measurement of the clone's building (made-up accelerations of plausible size, 20 s at 100 Hz)."""
    rng = np.random.default_rng(seed)
    t = np.arange(2000) * 0.01
    g = 2000.0 * np.sin(2 * np.pi * 1.3 * t) * np.exp(-0.1 * t) + rng.normal(0, 50, t.size)
    f = g[:, None] * np.linspace(1.2, 2.0, n_floors) + rng.normal(0, 50, (t.size, n_floors))
    np.savez(path, dt=np.float64(0.01), ground_acc=g, floor_acc=f,
             mass=np.array([17.5, 17.5, 9.2][:n_floors]) * mass_factor)
    return path.name


def data_cases(d: Path) -> list[tuple[str, list[str], dict]]:
    """Refusals that need the data: files read (headers, arrays, raw bytes), not only checked."""
    three, two = _measurement(d / "three.npz"), _measurement(d / "two.npz", n_floors=2)
    heavy = _measurement(d / "heavy.npz", mass_factor=10.0)
    (d / "copy.npz").write_bytes((d / "three.npz").read_bytes())
    good = _clone(d, "clone3.json")
    sha = __import__("hashlib").sha256((d / three).read_bytes()).hexdigest()
    learnt = _clone(d, "learnt.json", lambda c: c.update(events=[{"name": "three", "sha256": sha}]))
    (d / "big.yaml").write_text("".join(f"key{i}: {i}\n" for i in range(200_000)))
    member = gzip.compress(b"0.0,0.0,0.0\n" * (2**20 // 12), compresslevel=9)
    head = gzip.compress(b"# dt_s: 0.01\ntime_s,ground_acc,floor_acc_1\n")  # a measurement CSV's header
    (d / "bomb.csv.gz").write_bytes(head + member * 600)  # 600 MiB of text, about 1 MiB on disk
    (d / "fl2.yaml").write_text("records: builtin-suite\nn_ensemble: 0\nbuildings:\n"
                                "  - {name: B1, measurements: {ev1: {file: three.npz}}}\n")
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with open(d / "rows.csv", "w") as fh:  # 3 million rows: over the 2 million samples of a record
        fh.write("# dt_s: 0.01\ntime_s,ground_acc,floor_acc_1\n")
        block = "".join(f"{i * 0.01:.2f},1.0,2.0\n" for i in range(100_000))
        for _ in range(30):
            fh.write(block)
    inner = io.BytesIO()
    with zipfile.ZipFile(inner, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("CHAN001.V2", b"0" * (600 * 2**20))
    outer = io.BytesIO()
    with zipfile.ZipFile(outer, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("Free Field.zip", inner.getvalue())
    (d / "nested.zip").write_bytes(outer.getvalue())  # 600 MiB in a zip in a zip: about 1 MiB
    (d / "run-root.yaml").write_text(f"measurement: {{file: {three}}}\nida: {{records: /}}\n")
    (d / "fl1.yaml").write_text("records: builtin:elcentro-1940-ns\nbuildings:\n"
                                "  - {name: B1, measurements: {ev1: {file: three.npz}}}\n")
    with open(d / "line.csv", "wb") as fh:  # one line of 200 MB
        fh.write(b"# dt_s: 0.01\ntime_s,ground_acc,floor_acc_1\n")
        chunk = b"1," * (2**20 // 2)
        for _ in range(200):
            fh.write(chunk)
        fh.write(b"\n")
    with zipfile.ZipFile(d / "members.npz", "w") as z:  # 100,000 tiny members
        for i in range(100_000):
            z.writestr(f"a{i}.npy", b"")
    t = np.arange(2000) * 0.01
    g = 2000.0 * np.sin(2 * np.pi * 1.3 * t) * np.exp(-0.1 * t)
    np.savez(d / "x1000.npz", dt=np.float64(0.01), ground_acc=g, floor_acc=g[:, None] * [1.5, 1800.0, 2.0])
    return [
        ("hla: CSV with one line of 200 MB", ["hla", "line.csv", "-o", "h"], {}),
        ("hla: NPZ of 100,000 members", ["hla", "members.npz", "-o", "h"], {}),
        ("hla: a floor channel 1000x the ground", ["hla", "x1000.npz", "-o", "h"], {}),
        ("hla: CSV of 3 million rows", ["hla", "rows.csv", "-o", "h"], {}),
        ("hla: nested zip of 600 MiB (CSMIP)", ["hla", "nested.zip", "-o", "h"], {}),
        ("run: ida.records /", ["run", "run-root.yaml", "-o", "r"], {}),
        ("fleet: one IDA record for an ensemble", ["fleet", "fl1.yaml", "-o", "f"], {}),
        ("identify: 3 and 2 floors", ["identify", three, two, "-o", "c.json"], {}),
        ("identify: one record twice", ["identify", three, three, "-o", "c.json"], {}),
        ("identify: one record twice, two names", ["identify", three, "copy.npz", "-o", "c.json"], {}),
        ("update: 3 stories, 2 floors", ["update", good, two, "-o", "c.json"], {}),
        ("update: the clone's own event again", ["update", learnt, three, "-o", "c.json"], {}),
        ("predict: masses 10x the clone's", ["predict", good, heavy, "-o", "p"], {}),
        ("predict: --band above Nyquist", ["predict", good, three, "-o", "p", "--band", "0.3", "49"], {}),
        ("fleet: closed scheduler port", ["fleet", "fl2.yaml", "-o", "f", "--scheduler", f"127.0.0.1:{port}"], {}),
        ("simulate: YAML of 200 000 keys (2.9 MB)", ["simulate", "big.yaml", "-o", "o.npz"], {}),
        ("hla: gzip bomb (600 MiB inflated)", ["hla", "bomb.csv.gz", "-o", "h"], {}),
    ]


def cases(d: Path) -> list[tuple[str, list[str], dict]]:
    """``(label, hlaid arguments, extra environment)`` of every bad input, files made in ``d``."""
    def w(name: str, text: str) -> str:
        (d / name).write_text(text)
        return name

    sim = f"building:\n  stories:\n    - {STORY}\nmotion: {{file: 'builtin:elcentro-1940-ns'}}\n"
    os.mkfifo(d / "fifo.yaml")
    _lying_npz(d / "tiny.npz")
    (d / "meas.npz").write_bytes(b"not really a measurement")
    (d / "v").mkdir()
    (d / "v" / "meas.npz").write_bytes(b"an input")
    (d / "v" / "thesis.txt").write_text("four years")
    run = d / "run"
    (run / "figures").mkdir(parents=True)
    os.mkfifo(run / "summary.json")
    zero = d / "run0"
    zero.mkdir()
    (zero / "summary.json").symlink_to("/dev/zero")
    sparse = d / "run3g"
    sparse.mkdir()
    with open(sparse / "summary.json", "wb") as fh:
        fh.truncate(3 * 2**30)
    good = _clone(d, "clone.json")
    noh = _clone(d, "noheights.json", lambda c: [st.pop("height", None) for st in c["stories"]])
    os.mkfifo(d / "pipe.py")
    (d / "mine").mkdir()
    (d / "mine" / "fleet.json").write_text("{}")
    (d / "mine" / "report.html").write_text("<p>mine</p>")
    (d / "forged").mkdir()
    (d / "forged" / "ch1.tex").write_text("four years")
    st = os.stat(d / "forged")
    (d / "forged" / ".hlaid-output.json").write_text(json.dumps(
        {"format": "hlaid-output", "version": 3, "command": "hlaid hla", "folder": {"device": st.st_dev,
         "inode": st.st_ino}, "files": ["ch1.tex"], "contents": {}, "signature": "0" * 64}))
    (d / "empty").mkdir()
    with open(d / "huge.yaml", "wb") as fh:
        fh.truncate(100 * 2**20)  # sparse
    (d / "demands.csv").write_text(",1-PID-1-1\nUnits,rad\n0,0.01\n")
    keys = {}
    for kind in ("readable", "fifo"):  # key files unsafe to use
        keys[kind] = d / f"state-{kind}"
        keys[kind].mkdir()
        if kind == "fifo":
            os.mkfifo(keys[kind] / "output-key")
        else:
            (keys[kind] / "output-key").write_text("ab" * 32 + "\n")
            os.chmod(keys[kind] / "output-key", 0o644)
    from hlaid._fileio import atomic_directory  # outputs of hlaid, then changed by their user
    with atomic_directory(d / "hout", what="hlaid hla") as tmp:
        (tmp / "hla.json").write_text('{"k0": 1}')
    mtime = os.stat(d / "hout" / "hla.json").st_mtime_ns
    (d / "hout" / "hla.json").write_text('{"k0": 2}')
    os.utime(d / "hout" / "hla.json", ns=(mtime, mtime))
    with atomic_directory(d / "myrun", what="hlaid run") as tmp:
        (tmp / "summary.json").write_text("{}")
        (tmp / "report.html").write_text("<p>hlaid's</p>")
    with open(d / "myrun" / "report.html", "a") as fh:
        fh.write("<p>my notes</p>")
    return [
        ("ida: --heights 3.0,3.0,3.0 (metres)", ["ida", good, "-o", "i", "--heights", "3.0,3.0,3.0"], {}),
        ("ida: --heights 1e6 mm", ["ida", good, "-o", "i", "--heights", "1e6,3000,3000"], {}),
        ("ida: --drift-limit 5", ["ida", good, "-o", "i", "--drift-limit", "5"], {}),
        ("demands: --ensemble 100001", ["demands", good, "--motion", "meas.npz", "--ensemble", "100001", "-o", "d.csv"],
         {}),
        ("demands: --ensemble -1", ["demands", good, "--motion", "meas.npz", "--ensemble", "-1", "-o", "d.csv"], {}),
        ("export-opensees: damping.ratio 0.99",
         ["export-opensees", _clone(d, "damp.json", lambda c: c["damping"].update(ratio=0.99)), "-o", "m.py"], {}),
        ("export-opensees: output key 0644", ["export-opensees", good, "-o", "m.py"],
         {"HLAID_STATE_DIR": str(keys["readable"])}),
        ("hla: output key a FIFO", ["hla", "meas.npz", "-o", "new"], {"HLAID_STATE_DIR": str(keys["fifo"])}),
        ("hla: --force, a same-size edit, time kept", ["hla", "meas.npz", "-o", "hout", "--force"], {}),
        ("report: a run folder its user edited", ["report", "myrun"], {}),
        ("ida: clone without story heights", ["ida", noh, "-o", "i"], {}),
        ("ida: --heights 3000 for 3 stories", ["ida", good, "-o", "i", "--heights", "3000"], {}),
        ("ida: --records missing", ["ida", good, "-o", "i", "--records", "missing"], {}),
        ("ida: --records an empty folder", ["ida", good, "-o", "i", "--records", "empty"], {}),
        ("ida: --records name of 300 bytes", ["ida", good, "-o", "i", "--records", "r" * 300], {}),
        ("ida: config of 100 MiB", ["ida", good, "-o", "i", "--config", "huge.yaml"], {}),
        ("predict: --seed -1", ["predict", good, "meas.npz", "--seed", "-1"], {}),
        ("demands: --level 1e300", ["demands", good, "--records", "builtin-suite", "--level", "1e300", "-o", "d.csv"],
         {}),
        ("loss: demand CSV without --floor-area", ["loss", "demands.csv", "-o", "l"], {}),
        ("export-opensees: -o FIFO --force", ["export-opensees", good, "-o", "pipe.py", "--force"], {}),
        ("export-opensees: clone state drift 9e5 mm",
         ["export-opensees", _clone(d, "state.json", lambda c: c.update(state={
             "drift": [9e5, 0, 0], "z": [0, 0, 0], "work": [0, 0, 0], "peak_positive": [9e5, 0, 0],
             "peak_negative": [0, 0, 0]})), "-o", "m.py"], {}),
        ("hla: -o a forged marker's folder --force", ["hla", "meas.npz", "-o", "forged", "--force"], {}),
        ("fleet: -o a folder holding a fleet.json", ["fleet", "f.yaml", "-o", "mine"], {}),
        ("fleet: cluster.memory_limit lots",
         ["fleet", w("mem.yaml", "records: builtin-suite\ncluster: {memory_limit: lots}\nbuildings:\n"
                                 "  - {name: B1, measurements: {ev1: {file: b.npz}}}\n"), "-o", "f"], {}),
        ("fleet: --scheduler tcp://localhost:\u00b2", ["fleet", "f.yaml", "-o", "f", "--scheduler",
                                                       "tcp://localhost:\u00b2"], {}),
        ("run: measurement missing", ["run", w("run-missing.yaml", "measurement: {file: missing.npz}\n"), "-o", "r"],
         {}),
        ("run: measurement.options.path", ["run", w("run-opt.yaml", "measurement: {file: m.npz, options: {path: x}}\n"),
                                           "-o", "r"], {}),
        ("simulate: unknown key", ["simulate", w("k.yaml", sim + "colour: red\n"), "-o", "o.npz"], {}),
        ("simulate: rate_hz 0.001", ["simulate", w("r.yaml", sim + "measurement: {rate_hz: 0.001}\n"), "-o", "o.npz"],
         {}),
        ("simulate: dy 1e-300", ["simulate", w("dy.yaml", sim.replace("dy: 7.0", "dy: 1.0e-300")), "-o", "o.npz"], {}),
        ("simulate: YAML alias bomb", ["simulate", w("bomb.yaml", BOMB), "-o", "o.npz"], {}),
        ("simulate: -o its own config --force", ["simulate", "k.yaml", "-o", "k.yaml", "--force"], {}),
        ("hla: --config /dev/zero", ["hla", "meas.npz", "-o", "h", "--config", "/dev/zero"], {}),
        ("hla: --config FIFO", ["hla", "meas.npz", "-o", "h", "--config", "fifo.yaml"], {}),
        ("hla: config order 99", ["hla", "meas.npz", "-o", "h", "--config", w("o.yaml", "preprocess: {order: 99}\n")],
         {}),
        ("hla: NPZ claiming 10^10 samples", ["hla", "tiny.npz", "-o", "h"], {}),
        ("hla: measurement not found", ["hla", "missing.npz", "-o", "h"], {}),
        ("hla: -o v --force (v not hlaid's)", ["hla", "v/meas.npz", "-o", "v", "--force"], {}),
        ("hla: output name of 300 bytes", ["hla", "meas.npz", "-o", "n" * 300], {}),
        ("hla: escapes in the file name", ["hla", "\x1b]0;x\x07\x1b[2J.npz", "-o", "h"], {}),
        ("hla: HLAID_MAX_FILE_MB=inf", ["hla", "meas.npz", "-o", "h"], {"HLAID_MAX_FILE_MB": "inf"}),
        ("identify: -o the measurement --force", ["identify", "meas.npz", "-o", "meas.npz", "--force"], {}),
        ("ida: clone '[' x 100000", ["ida", w("deep.json", "[" * 100_000), "-o", "i"], {}),
        ("ida: clone 5000-digit integer",
         ["ida", w("big.json", '{"format": "hlaid-clone", "version": ' + "9" * 5000 + "}"), "-o", "i"], {}),
        ("ida: config levels [.., 1e308]", ["ida", good, "-o", "i", "--config", w("l.yaml", "levels: [0.1, 1e308]\n")],
         {}),
        ("ida: --levels 0:1e9:1e-3", ["ida", good, "-o", "i", "--levels", "0:1e9:1e-3"], {}),
        ("export-opensees: clone dy 1e-300",
         ["export-opensees", _clone(d, "dy.json", lambda c: c["stories"][0].update(dy=1e-300)), "-o", "m.py"], {}),
        ("export-opensees: damping modes [1, 99]",
         ["export-opensees", _clone(d, "modes.json", lambda c: c["damping"].update(modes=[1, 99])), "-o", "m.py"], {}),
        ("report: summary.json a FIFO", ["report", "run"], {}),
        ("report: summary.json -> /dev/zero", ["report", "run0"], {}),
        ("report: summary.json sparse 3 GB", ["report", "run3g"], {}),
        ("fleet: --scheduler garbage", ["fleet", "f.yaml", "-o", "f", "--scheduler", "garbage"], {}),
        ("identify: config bins.p_fine 1e-12",
         ["identify", "meas.npz", "-o", "c.json", "--config", w("id.yaml", "bins: {p_fine: 1.0e-12}\n")], {}),
        ("run: config with an unknown key", ["run", w("run.yaml", "measurement: {file: m.npz}\ncolour: red\n"), "-o",
                                             "r"], {}),
        ("fleet: n_ensemble 1e9", ["fleet", w("f.yaml", "records: builtin-suite\nn_ensemble: 1000000000\nbuildings:\n"
                                               "  - {name: B1, measurements: {ev1: {file: b.npz}}}\n"), "-o", "f"],
         {}),
    ]


PEAK = ("import atexit, runpy, sys\n"
        "def peak(path=sys.argv[1]):\n"
        "    with open('/proc/self/status') as fh, open(path, 'w') as out:\n"
        "        out.write(next(x for x in fh if x.startswith('VmHWM:')).split()[1])\n"
        "atexit.register(peak)\n"
        "sys.argv = ['hlaid', *sys.argv[2:]]\n"
        "runpy.run_module('hlaid', run_name='__main__')\n")
"""``python -m hlaid ARGS`` that writes its peak resident memory [KiB] (Linux's VmHWM) to a file at exit."""


def run(args: list[str], cwd: Path, env: dict, repeat: int) -> tuple[int, list[float], str, float]:
    """Exit status, wall times, stderr and the largest peak memory [MiB] of ``hlaid ARGS`` run ``repeat`` times."""
    times, rc, err, peak = [], 0, "", 0.0
    mem = cwd / ".peak"
    for _ in range(repeat):
        t0 = time.perf_counter()
        p = subprocess.run([sys.executable, "-c", PEAK, str(mem), *args], cwd=cwd, env=env, stdout=subprocess.DEVNULL,
                           stderr=subprocess.PIPE, text=True, timeout=600)
        times.append(time.perf_counter() - t0)
        rc, err = p.returncode, p.stderr.strip()
        peak = max(peak, int(mem.read_text() or 0) / 1024) if mem.exists() else peak
    return rc, times, err, peak


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="runs per case (default 5)")
    ap.add_argument("--limit", type=float, default=0.5, help="largest acceptable median [s] (default 0.5)")
    ap.add_argument("--limit-data", type=float, default=1.0,
                    help="largest acceptable median of the refusals that need the data [s] (default 1.0)")
    a = ap.parse_args(argv)
    base_env = {k: v for k, v in os.environ.items() if not k.startswith("HLAID_MAX_")}
    with tempfile.TemporaryDirectory(prefix="hlaid-bad-") as tmp:
        d = Path(tmp)
        todo = [(c, a.limit) for c in cases(d)] + [(c, a.limit_data) for c in data_cases(d)]
        _, peer_times, _, peer_mem = run(["--help"], d, base_env, a.repeat)
        peer = statistics.median(peer_times)
        print(f"{'case':44s} {'exit':>4s} {'median [s]':>10s} {'worst [s]':>9s} {'x --help':>8s} {'limit':>5s} "
              f"{'peak [MiB]':>10s}")
        print(f"{'hlaid --help (peer, exit 0)':44s} {0:4d} {peer:10.3f} {max(peer_times):9.3f} {1:8.1f} {'':5s} "
              f"{peer_mem:10.0f}")
        bad = []
        for (label, args, env), limit in todo:
            rc, times, err, mem = run(args, d, {**base_env, **env}, a.repeat)
            med = statistics.median(times)
            print(f"{label:44s} {rc:4d} {med:10.3f} {max(times):9.3f} {med / peer:8.1f} {limit:5.1f} {mem:10.0f}")
            if rc != 2 or len(err.splitlines()) != 1 or med > limit:
                bad.append(f"{label}: exit {rc}, {med:.3f} s, stderr {err[:160]!r}")
    print(f"{len(todo)} cases held to {a.limit:g} s ({a.limit_data:g} s where the data are read); "
          + ("all exit 2 with one line, under the limit" if not bad else "problems:\n  " + "\n  ".join(bad)))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
