"""``hlaid demo``: the whole pipeline on the embedded Table 1 case (``hlaid/data/demo.yaml``)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from .run.config import load_run_config


def demo_config():
    """The embedded demo run config (a copy of ``configs/demo.yaml``)."""
    with resources.as_file(resources.files("hlaid").joinpath("data/demo.yaml")) as p:
        return load_run_config(p)


def run_demo(out: str | Path = "hlaid-demo", *, force: bool = False, cache_dir: str | None = None) -> Path:
    """Run the demo and write its outputs under ``out`` (report.html, clone.json, ...)."""
    import time

    from . import _progress, _warmup
    from .run.runner import run_pipeline
    t0 = time.perf_counter()
    if _warmup.warm():  # a fresh install: the kernels compiled in parallel, once
        _progress.info(f"compiled the numerical kernels once for this installation in {time.perf_counter() - t0:.0f} s")
    run_pipeline(demo_config(), out, force=force, cache_dir=cache_dir)
    return Path(out)
