"""The table of a parameter sweep (``bench table RESULTS --sweep``, and printed by ``bench run``
for an experiment with sweeps): one row per sweep point, the mean relative error per segment
length over the sweep's sequences (rotation [deg] / translation [m]), the best point per length
in bold, and the point the experiment's criterion chooses beside the method's default. Under
the tuning rule of configs/splits.yaml (bench/runs/tuning_rule.py) each row also shows the
point's criterion ``C`` with its interval per fold (tuning and validation sequences) and on the
second domain, and why it qualifies or not; the decision follows the table.

The sweep's layout comes from ``<results>/sweeps.json`` (bench/runs/sweep.py)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from bench.runs.folders import read_run
from bench.runs.sweep import format_value, read_sweep_index
from bench.runs.tuning_rule import Decision, RunErrors, decide, run_errors
from loaders.errors import DataError

UNITS = {"rotation": "deg", "translation": "m", "both": "(relative to the points' mean)"}


@dataclass
class Choice:
    """The point a sweep's criterion chose for one seed option."""

    method: str
    group: str
    seed: bool | None
    point: dict | None          # None when no point has every run finished
    value: float | None         # its criterion value
    default: dict | None        # the method's default for the swept keys (None: differs by
    #                             sequence)
    missing: list[str]          # labels of points with a run missing (failed or not run)
    decision: Decision | None = None  # the tuning rule's decision (cross-validated criterion)

    @property
    def agrees(self) -> bool:
        return self.point is not None and self.default is not None and all(
            _same(self.point[k], self.default.get(k)) for k in self.point)

    def describe(self, criterion: dict) -> str:
        if criterion.get("folds") is not None:
            return self._describe_rule()
        if self.point is None:
            return f"{self.group}: no point has every run finished"
        point = " ".join(f"{k}={format_value(v)}" for k, v in self.point.items())
        lengths = ", ".join(f"{x:g}" for x in criterion["lengths_m"])
        seed = {True: " (with seed)", False: " (no seed)", None: ""}[self.seed]
        error = ("rotation and translation" if criterion["error"] == "both"
                 else criterion["error"])
        text = (f"chosen{seed}: {self.method} {point} (mean {error} error at "
                f"{lengths} m: {self.value:.4g} {UNITS[criterion['error']]}")
        if criterion.get("tie_within"):
            text += f"; points within {100 * criterion['tie_within']:g} % of the best tie, "
            text += "the first listed wins"
        if criterion.get("keep_default_within"):
            text += (f"; the default stays unless beaten by more than "
                     f"{100 * criterion['keep_default_within']:g} %")
        return self._against_default(text + ")")

    def _against_default(self, text: str) -> str:
        """``text`` followed by how the choice stands against the method's default and which
        points are not finished."""
        if self.default is None:
            return text + "; the default differs by sequence"
        default = " ".join(f"{k}={format_value(v)}" for k, v in self.default.items())
        text += f"; default {default}: " + ("agrees" if self.agrees else "DIFFERS")
        if self.missing:
            text += f"; not finished: {', '.join(self.missing)}"
        return text

    def _describe_rule(self) -> str:
        seed = {True: " (with seed)", False: " (no seed)", None: ""}[self.seed]
        d = self.decision
        point = ("undecided" if self.point is None else
                 self.method + " " + " ".join(f"{k}={format_value(v)}"
                                              for k, v in self.point.items()))
        return self._against_default(
            f"chosen{seed}: {point} (the tuning rule of configs/splits.yaml: {d.text})")


def _same(a, b) -> bool:
    if isinstance(a, int | float) and isinstance(b, int | float):
        return abs(a - b) <= 1e-9 * max(1.0, abs(a), abs(b))
    return a == b


def _errors(index: dict, results_dir: Path, sweep: dict, seed) -> tuple[list, list[float]]:
    """Per point: {length: (rot, trans) mean over the sweep's sequences} (None when a run is
    missing); and the lengths in order."""
    rows, lengths = [], []
    for p in sweep["points"]:
        runs = [read_run(results_dir / r["dir"]) for r in p["runs"] if r["seed"] == seed]
        if not runs or any(r is None for r in runs):
            rows.append(None)
            continue
        per_length: dict[float, list] = {}
        for run in runs:
            for rel in run.result.relative_error:
                if rel.n:
                    per_length.setdefault(float(rel.length_m), []).append(
                        (rel.rot_deg_mean, rel.trans_m_mean))
        cells = {}
        for length, values in per_length.items():
            if len(values) == len(runs):  # every sequence has segments of this length
                cells[length] = tuple(sum(v[i] for v in values) / len(values) for i in (0, 1))
                if length not in lengths:
                    lengths.append(length)
        rows.append(cells)
    return rows, sorted(lengths)


def _criterion_values(rows: list[dict | None], criterion: dict) -> list[float | None]:
    """Each point's criterion value (None when a run or a criterion length is missing)."""
    lengths = [float(x) for x in criterion["lengths_m"]]
    complete = [c if c is not None and all(x in c for x in lengths) else None for c in rows]
    if criterion["error"] != "both":
        i = 0 if criterion["error"] == "rotation" else 1
        return [None if c is None else sum(c[x][i] for x in lengths) / len(lengths)
                for c in complete]
    scored = [c for c in complete if c is not None]
    if not scored:
        return [None] * len(rows)
    # each error over the points' mean, so that degrees and metres weigh alike
    mean = {(x, i): sum(c[x][i] for c in scored) / len(scored) for x in lengths for i in (0, 1)}
    return [None if c is None else sum(c[x][i] / mean[(x, i)] for x in lengths for i in (0, 1))
            / (2 * len(lengths)) for c in complete]


def _choose(values: list[float | None], criterion: dict, default: int | None = None
            ) -> int | None:
    """The chosen point: the first within ``tie_within`` of the lowest value; the
    ``default``'s point instead when the choice does not beat it by more than
    ``keep_default_within``."""
    scored = [v for v in values if v is not None]
    if not scored:
        return None
    best = min(scored)
    tie, keep = criterion.get("tie_within", 0.0), criterion.get("keep_default_within", 0.0)
    chosen = next(i for i, v in enumerate(values) if v is not None and v <= best * (1 + tie))
    if keep and default is not None and values[default] is not None \
            and values[chosen] * (1 + keep) >= values[default]:
        return default
    return chosen


def _default_index(sweep: dict) -> int | None:
    default = _default(sweep)
    if default is None:
        return None
    return next((i for i, p in enumerate(sweep["points"])
                 if all(_same(v, default.get(k)) for k, v in p["point"].items())), None)


def _seeds(sweep: dict) -> list:
    return list(dict.fromkeys(r["seed"] for p in sweep["points"] for r in p["runs"]))


def _default(sweep: dict) -> dict | None:
    values = list(sweep["defaults"].values())
    return values[0] if values and all(v == values[0] for v in values) else None


def _run_errors(results_dir: Path, sweep: dict, seed, lengths) -> list[dict | None]:
    """Per point: sequence name -> RunErrors of its run (None when a run is missing)."""
    out = []
    for p in sweep["points"]:
        runs = {r["sequence"]: read_run(results_dir / r["dir"]) for r in p["runs"]
                if r["seed"] == seed}
        if not runs or any(r is None for r in runs.values()):
            out.append(None)
            continue
        out.append({name: run_errors(r.gt, r.est, lengths) for name, r in runs.items()})
    return out


def _reference_index(sweep: dict, criterion: dict) -> int:
    """The index of the rule's reference point: the criterion's ``reference`` values, the
    method's default for the keys it does not give."""
    default = _default(sweep) or {}
    want = {k: criterion.get("reference", {}).get(k, default.get(k)) for k in sweep["keys"]}
    for i, p in enumerate(sweep["points"]):
        if all(_same(v, want[k]) for k, v in p["point"].items()):
            return i
    text = " ".join(f"{k}={format_value(v)}" for k, v in want.items())
    raise DataError(f"sweep {sweep['group']}: its reference point {text} (the criterion's "
                    "reference, else the method's default) is not a point of the grid")


def rule_decision(results_dir: Path, sweep: dict, seed, criterion: dict) -> Decision:
    """The tuning rule's decision over one sweep and seed option."""
    lengths = [float(x) for x in criterion["lengths_m"]]
    errors: list[dict[str, RunErrors] | None] = _run_errors(results_dir, sweep, seed, lengths)
    folds = [(f["tuning"], f["validation"]) for f in criterion["folds"]]
    return decide([p["point"] for p in sweep["points"]], errors,
                  _reference_index(sweep, criterion), folds, criterion.get("domain", []),
                  lengths, criterion.get("level", 0.95), criterion.get("reps", 1000),
                  min_gain=criterion.get("min_gain", 0.0))


def _decisions(results_dir: Path, index: dict) -> dict:
    criterion = index.get("criterion")
    if not criterion or criterion.get("folds") is None:
        return {}
    return {(sweep["group"], seed): rule_decision(results_dir, sweep, seed, criterion)
            for sweep in index["sweeps"] for seed in _seeds(sweep)}


def sweep_choices(results_dir: Path, decisions: dict | None = None) -> list[Choice]:
    """The point each sweep's criterion chooses (per seed option), with the default beside it;
    empty when the experiment names no criterion."""
    results_dir = Path(results_dir)
    index = read_sweep_index(results_dir)
    criterion = index.get("criterion")
    if criterion is None:
        return []
    if decisions is None:
        decisions = _decisions(results_dir, index)
    choices = []
    for sweep in index["sweeps"]:
        for seed in _seeds(sweep):
            if criterion.get("folds") is not None:
                d = decisions[(sweep["group"], seed)]
                missing = [p["label"] for p, v in zip(sweep["points"], d.verdicts, strict=True)
                           if v.overall is None]
                point = None if d.chosen is None else sweep["points"][d.chosen]["point"]
                value = None if d.chosen is None else d.verdicts[d.chosen].overall
                choices.append(Choice(sweep["method"], sweep["group"], seed, point, value,
                                      _default(sweep), missing, d))
                continue
            rows, _ = _errors(index, results_dir, sweep, seed)
            values = _criterion_values(rows, criterion)
            best = _choose(values, criterion, _default_index(sweep))
            missing = [p["label"] for p, v in zip(sweep["points"], values, strict=True)
                       if v is None]
            choices.append(Choice(sweep["method"], sweep["group"], seed,
                                  None if best is None else sweep["points"][best]["point"],
                                  None if best is None else values[best], _default(sweep),
                                  missing))
    return choices


def sweep_markdown(results_dir: Path) -> str:
    """Every sweep of ``results_dir`` as a markdown table (one per sweep and seed option), the
    best point per length in bold (rotation and translation separately), then each choice."""
    results_dir = Path(results_dir)
    index = read_sweep_index(results_dir)
    criterion = index.get("criterion")
    decisions = _decisions(results_dir, index)
    choices = {(c.group, c.seed): c for c in sweep_choices(results_dir, decisions)}
    out = []
    for sweep in index["sweeps"]:
        sequences = sorted({r["sequence"] for p in sweep["points"] for r in p["runs"]})
        default = _default(sweep)
        for seed in _seeds(sweep):
            rows, lengths = _errors(index, results_dir, sweep, seed)
            seed_text = {True: "with seed", False: "no seed", None: "no initial guess"}[seed]
            out.append(f"### {sweep['group']}: sweep of {', '.join(sweep['keys'])} "
                       f"({seed_text}; mean over {', '.join(sequences)})\n")
            decision = decisions.get((sweep["group"], seed))
            groups = [] if decision is None else list(dict.fromkeys(
                g for v in decision.verdicts for g in v.estimates))
            head = ["Point"] + [f"{x:g} m" for x in lengths]
            if decision is not None:
                head += [f"C {g}" for g in groups] + ["C all folds", "Verdict"]
            elif criterion:
                head.append(f"Criterion ({criterion['error']}, "
                            f"{', '.join(f'{x:g}' for x in criterion['lengths_m'])} m)")
            out.append("| " + " | ".join(head) + " |")
            out.append("|" + "---|" * len(head))
            best = {(x, i): min((c[x][i] for c in rows if c and x in c), default=None)
                    for x in lengths for i in (0, 1)}
            choice = choices.get((sweep["group"], seed))
            values = (_criterion_values(rows, criterion) if criterion and decision is None
                      else [None] * len(rows))
            for n, (p, cells, v) in enumerate(zip(sweep["points"], rows, values, strict=True)):
                name = " ".join(f"{k}={format_value(v)}" for k, v in p["point"].items())
                if default is not None and all(_same(v, default.get(k))
                                               for k, v in p["point"].items()):
                    name += " (default)"
                if decision is not None and n == decision.reference:
                    name += " (reference)"
                row = [name]
                for x in lengths:
                    if not cells or x not in cells:
                        row.append("-")
                        continue
                    parts = [f"{cells[x][i]:.3f}" for i in (0, 1)]
                    parts = [f"**{t}**" if cells[x][i] == best[(x, i)] else t
                             for i, t in enumerate(parts)]
                    row.append(" / ".join(parts))
                if decision is not None:
                    verdict = decision.verdicts[n]
                    row += [str(verdict.estimates[g]) if g in verdict.estimates else "-"
                            for g in groups]
                    row.append("-" if verdict.overall is None else f"{verdict.overall:.3f}")
                    why = verdict.why
                    if choice and choice.point == p["point"]:
                        why = f"**chosen**: {why}"
                    row.append(why)
                elif criterion:
                    text = "failed or not run" if cells is None else (
                        "-" if v is None else f"{v:.4f}")
                    if choice and choice.point == p["point"]:
                        text = f"**{text} chosen**"
                    row.append(text)
                out.append("| " + " | ".join(row) + " |")
            out.append("")
            out.append("Each cell: mean rotation [deg] / translation [m] relative error per "
                       "segment length, averaged over the sweep's sequences; best per length "
                       "in bold.")
            if decision is not None:
                lengths_text = ", ".join(f"{x:g}" for x in criterion["lengths_m"])
                out.append(f"C: mean over {lengths_text} m and both errors of the error "
                           "divided by the reference point's (1 = the reference, lower is "
                           f"better), {100 * criterion.get('level', 0.95):g} % block-bootstrap "
                           "interval in brackets (configs/splits.yaml).")
            if choice is not None:
                out.append("")
                out.append(choice.describe(criterion))
            out.append("")
    if index.get("default_differs"):
        out.append(f"Why the default differs: {index['default_differs'].strip()}")
        out.append("")
    return "\n".join(out)
