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
    from .run.runner import run_pipeline
    run_pipeline(demo_config(), out, force=force, cache_dir=cache_dir)
    return Path(out)
