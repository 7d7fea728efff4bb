"""``make reproduce-table``: the paper's Table III with every registered method.

Real stores listed in ``configs/datasets/*.yaml`` and present under ``DATA_DIR/real/`` are used
when there are any; otherwise the synthetic suite ``synthetic-paper`` is generated (or reused
from its cache) and used.
"""

from __future__ import annotations

import time
from pathlib import Path

import yaml
from rich.console import Console

from bench.experiment import Experiment, MethodEntry, SequenceEntry
from bench.figures import plot_trajectories
from bench.run import execute, summarize
from bench.runplan import jobs_for_experiment
from bench.tables import write_tables
from methods.registry import METHODS

DATASETS_DIR = Path(__file__).resolve().parent.parent / "configs" / "datasets"


def real_sequences(data_dir: Path) -> list[SequenceEntry]:
    """Paper sequences whose converted store exists under ``data_dir/real``."""
    entries = []
    for cfg_path in sorted(DATASETS_DIR.glob("*.yaml")):
        cfg = yaml.safe_load(cfg_path.read_text()) or {}
        store = data_dir / "real" / cfg.get("store", f"{cfg.get('name', cfg_path.stem)}.h5")
        if store.exists():
            entries.append(SequenceEntry(path=store, name=cfg.get("name", cfg_path.stem),
                                         display_name=cfg.get("display_name"),
                                         sensor_class=cfg.get("sensor_class")))
    return entries


def reproduce_table(out: Path, data_dir: Path, jobs: int, force: bool, synthetic_only: bool,
                    console: Console) -> dict[str, str]:
    t0 = time.perf_counter()
    methods = [MethodEntry(name=name) for name in METHODS]
    real = [] if synthetic_only else real_sequences(data_dir)
    if real:
        console.print(f"[bold]real stores[/]: {', '.join(s.name for s in real)}")
        exp = Experiment(name="paper-real", sequences=real, methods=methods, jobs=jobs,
                         out=out if out != Path("results/paper-synthetic")
                         else Path("results/paper-real"))
    else:
        console.print(f"[bold]no real stores under {data_dir / 'real'}[/]: using the "
                      "synthetic suite 'synthetic-paper'")
        exp = Experiment(name="paper-synthetic", suite="synthetic-paper", data_dir=data_dir,
                         methods=methods, jobs=jobs, out=out)
    outcomes = execute(jobs_for_experiment(exp, console), jobs, force, console)
    texts = write_tables(exp.out_dir)
    figures = plot_trajectories(exp.out_dir)
    console.print(texts["md"], markup=False, highlight=False)
    if figures:
        console.print(f"trajectory figures: {figures[0].parent}/")
    console.print(f"[bold]{summarize(outcomes)}[/] in {time.perf_counter() - t0:.0f} s; wrote "
                  f"{exp.out_dir}/table.{{md,tex,csv}}")
    return texts
