"""A method's margins against its targets, on tuning data and on held-out data side by side
(`dpcbench margins`).

A **row** is one (experiment, data, damage): the run's identity without its seed, as the run spec
hashes it (`bench.experiment.config.RunSpec.identity`: the sequence without its label or path, the data
fingerprint, the hole generator and its parameters, the region protocol), never a display label;
its observations pair up by (seed, frame) across methods (seeds pooled, as in the tables). Frame-
level metrics give one value per (seed, frame); temporal consistency, a sequence-level metric, one
per seed (frame -1). Of several runs of one cell (row, seed, method configuration) the newest
enters (a store keeps the runs of older code versions).

Per row and target (`TARGETS`, issue 53's list, and `COLOUR_TARGETS`, issue 54's, on the rows that scored
colour), with ``x`` the method's values and ``y`` those of the method it is measured against, over the n pairs
both have with finite values:

    d_i = s * (x_i - y_i)          s = +1 where higher is better (PSNR), -1 where lower is (NSHD, TC)

so ``d > 0`` means the method did better; the margin is ``mean(d)``, with the bootstrap 95% interval of that
mean that resamples whole damages (a seed with all its frames: `bench.results.stats.mean_difference_interval`
with the seeds as groups; the frames of one damage are not independent pairs) and the two-sided Wilcoxon signed-
rank p-value of ``d - t`` (`bench.results.stats.signed_rank_p`), t the target's threshold. "Against" is
either the floor (``none``: no fill) or the best other method of the row (the best mean, sign
included; every configuration of every other method, ``none`` too). A target is **met** when
``mean(d) >= t``; the verdict says whether that is beyond noise:

    met                    the interval lies above t (low > t) and p <= ALPHA
    missed                 the interval lies below t (high < t) and p <= ALPHA
    met / missed, within noise     otherwise
    ..., n too small       n < stats.min_pairs(1): no test of n pairs can reach ALPHA

Beside it, seed by seed (a seed is one damage of the row: one draw of its holes), how many seeds' own mean of d
meets the threshold: a row's mean can meet a target that some of its damages miss (`MarginReport.seed_line` counts
those rows).

With the smooth-surface oracle (`oracle_observations`, ``dpcbench margins --oracle``: samples on the ground
truth's own smooth surface at the damaged frame's spacing, neither at the truth's sample places nor with their own
offsets from the surface, `bench.results.oracle` variant ``smooth``, scored on each cell's damaged
frames as the runs are scored) two more margins are shown: the oracle's D1 minus the best method
other than the measured one, and its D2 minus no fill. A row where the method misses a target and
the oracle misses it too, beyond noise, is out of reach by measurement (`out_of_reach_line`). The
oracle is never "another method" of a row.

A role (`experiment.data_role` in the config: "tuning" or "heldout") is read from the runs' stored
specs, else from the preset (bench/presets/*.toml) of that experiment name (runs recorded before
the key existed), else "unmarked". The held-out check counts the damaged inputs (data, damage,
seed) a held-out experiment shares with the experiment it holds out from: any shared input means
the held-out data is not held out.
"""

from __future__ import annotations

import csv
import io
import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from dpcbench.bench.core.canonical import sorted_json
from dpcbench.bench.core.errors import UserError
from dpcbench.bench.reporting.computed_with import computed_with_notes, env_isa
from dpcbench.bench.reporting.tables import csv_safe, md_escape
from dpcbench.bench.results import stats

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10, as bench.experiment.config
    import tomli as tomllib

FLOOR = "none"
ROLES = ("tuning", "heldout", "unmarked")
ROLE_TITLES = {"tuning": "tuning data", "heldout": "held-out data", "unmarked": "data of no declared role"}
#: columns of the tidy observations `compute_margins` takes
OBS_COLUMNS = ["experiment", "row", "row_label", "method", "seed", "frame", "metric", "scope", "peak", "value"]
PRESETS = Path(__file__).resolve().parents[1] / "presets"

MET, MISSED = "met", "missed"
WITHIN = "within noise"
TOO_FEW = "n too small"


@dataclass(frozen=True)
class Target:
    """One of the method's targets: ``mean(d) >= threshold`` against ``against`` ("floor" or "best")."""

    key: str
    title: str          # the count line's wording
    metric: str
    scope: str
    peak: str
    against: str        # "floor" (no fill) or "best" (the best other method of the row)
    threshold: float
    higher_is_better: bool
    heading: str        # the table column

    def margin_text(self) -> str:
        return self.heading


#: issue 53's targets: whole-frame D1 >= best other + 1 dB, whole-frame D2 at or above no fill, NSHD
#: at or below every other's, temporal consistency in the holes the best
TARGETS = (
    Target("d1", "D1 >= best other + 1 dB", "gpsnr_d1", "frame", "intrinsic", "best", 1.0, True,
           "D1 − best other (dB)"),
    Target("d2", "D2 at or above no fill", "gpsnr_d2", "frame", "intrinsic", "floor", 0.0, True,
           "D2 − no fill (dB)"),
    Target("nshd", "NSHD at or below every other's", "nshd", "frame", "", "best", 0.0, False,
           "best other's NSHD − its NSHD"),
    Target("tc", "temporal consistency in the holes the best", "temporal_consistency", "holes", "", "best", 0.0,
           False, "best other's TC − its TC (holes)"),
)

#: issue 54's target, on the rows whose sequence carries colour and whose experiment scored ``cpsnr_y``: the
#: method's colour PSNR of luma (pc_error's BT.709 Y) in the hole regions the highest of all methods
COLOUR_TARGETS = (
    Target("colour", "colour (cpsnr_y) in the holes the best", "cpsnr_y", "holes", "", "best", 0.0, True,
           "Y in the holes − best other's (dB)"),
)


#: observations of an oracle fill (`bench.results.oracle`) carry this method label prefix; they are never "another method"
ORACLE_PREFIX = "oracle: "
#: the oracle whose margins `dpcbench margins --oracle` shows: the truth's smooth surface, neither at its samples'
#: places nor with their offsets from it (the ``surface`` oracle keeps those offsets: on voxelized data its D2 is
#: about 20 dB above the smooth one's, out of any fill's reach, so a target it reaches says little)
MARGIN_ORACLE = "smooth"
#: the oracle margins shown beside the method's (`add_oracle`): what a fill on the truth's own surface
#: reaches against the same references as the method's D1 and D2 targets
ORACLE_TARGETS = (
    Target("oracle_d1", "smooth-surface oracle D1 >= best other + 1 dB", "gpsnr_d1", "frame", "intrinsic", "best",
           1.0, True, "smooth-surface oracle: D1 − best other (dB)"),
    Target("oracle_d2", "smooth-surface oracle D2 at or above no fill", "gpsnr_d2", "frame", "intrinsic", "floor",
           0.0, True, "smooth-surface oracle: D2 − no fill (dB)"),
)


@dataclass
class Margin:
    target: Target
    against: str | None      # the method measured against (None: no other method with values)
    method_mean: float
    against_mean: float
    margin: float            # mean(d), d oriented so that > 0 is better for the method
    low: float
    high: float
    n: int
    p_value: float           # Wilcoxon signed-rank of d - threshold, two-sided
    seeds: int = 0           # the seeds (damages) behind the n pairs
    seeds_met: int = 0       # those whose own mean of d meets the threshold

    @property
    def defined(self) -> bool:
        return self.against is not None and self.n > 0 and math.isfinite(self.margin)

    @property
    def met(self) -> bool:
        return self.defined and self.margin >= self.target.threshold

    @property
    def beyond_noise(self) -> bool:
        t = self.target.threshold
        return (self.defined and self.n >= stats.min_pairs(1) and self.p_value <= stats.ALPHA
                and (self.low > t if self.met else self.high < t))

    @property
    def verdict(self) -> str:
        if not self.defined:
            return "no value"
        word = MET if self.met else MISSED
        if self.n < stats.min_pairs(1):
            return f"{word}, {TOO_FEW}"
        return word if self.beyond_noise else f"{word}, {WITHIN}"


@dataclass
class MarginRow:
    experiment: str
    role: str
    row: str                 # the row's identity (canonical JSON), what rows are grouped by
    label: str
    method: str
    margins: dict[str, Margin] = field(default_factory=dict)
    means: dict[str, float] = field(default_factory=dict)   # the method's own D1 / D2 means


@dataclass
class MarginReport:
    method: str
    rows: list[MarginRow]
    roles: dict[str, tuple[str, str | None]]   # experiment -> (role, holds_out)
    notes: list[str] = field(default_factory=list)

    def targets(self) -> tuple[Target, ...]:
        """TARGETS, COLOUR_TARGETS where a row scored colour, and ORACLE_TARGETS where an oracle was scored
        (`add_oracle`)."""
        def present(targets):
            return any(t.key in r.margins for r in self.rows for t in targets)

        return (TARGETS + (COLOUR_TARGETS if present(COLOUR_TARGETS) else ())
                + (ORACLE_TARGETS if present(ORACLE_TARGETS) else ()))

    def out_of_reach_line(self, role: str) -> str | None:
        """How many rows that miss a D1 / D2 target the oracle misses too, beyond noise."""
        if not any(t.key in r.margins for r in self.rows if r.role == role for t in ORACLE_TARGETS):
            return None
        parts = []
        for mine, oracle in (("d1", "oracle_d1"), ("d2", "oracle_d2")):
            rows = [r for r in self.rows if r.role == role and oracle in r.margins and r.margins[mine].defined
                    and not r.margins[mine].met]
            beyond = sum(1 for r in rows if not r.margins[oracle].met and r.margins[oracle].beyond_noise)
            parts.append(f"{mine.upper()}: {beyond} of the {len(rows)} rows that miss it")
        return ("out of reach by measurement (the smooth-surface oracle misses the same target beyond noise): "
                + "; ".join(parts))

    def roles_present(self) -> list[str]:
        have = {r.role for r in self.rows}
        return [r for r in ROLES if r in have]

    def counts(self, role: str, target: Target) -> dict[str, int]:
        """rows (with a value), met, met beyond noise, missed beyond noise, for one role and target."""
        margins = [r.margins[target.key] for r in self.rows
                   if r.role == role and target.key in r.margins and r.margins[target.key].defined]
        return {"rows": len(margins), "met": sum(m.met for m in margins),
                "met_beyond": sum(m.met and m.beyond_noise for m in margins),
                "missed_beyond": sum((not m.met) and m.beyond_noise for m in margins)}

    def seed_line(self, role: str, target: Target) -> str | None:
        """How many of the rows that meet ``target`` on their mean hold a seed (a damage) whose own mean misses it;
        None where no row of ``role`` has more than one seed or none meets the target."""
        margins = [r.margins[target.key] for r in self.rows
                   if r.role == role and target.key in r.margins and r.margins[target.key].defined]
        met = [m for m in margins if m.met]
        if not any(m.seeds > 1 for m in met):
            return None
        below = [m for m in met if m.seeds_met < m.seeds]
        return (f"{target.title}, seed by seed: {len(below)} of the {len(met)} rows that meet it on the mean have a "
                f"seed that misses it on its own ({sum(m.seeds - m.seeds_met for m in below)} such seeds)")

    def count_line(self, role: str, target: Target) -> str:
        c = self.counts(role, target)
        return (f"{target.title} on {c['met']} of {c['rows']} rows ({c['met_beyond']} beyond noise; "
                f"{c['missed_beyond']} missed beyond noise)")

    # -- output ---------------------------------------------------------------------------
    def markdown(self, command: str | None = None) -> str:
        lines = [f"# Margins of {md_escape(self.method)}: tuning and held-out data", ""]
        if command:
            lines += [f"Made by `{command}`.", ""]
        roles = self.roles_present()
        targets = self.targets()
        lines += ["| target | " + " | ".join(ROLE_TITLES[r] for r in roles) + " |",
                  "|---|" + "---|" * len(roles)]
        for t in targets:
            cells = []
            for r in roles:
                c = self.counts(r, t)
                cells.append(f"{c['met']} of {c['rows']} ({c['met_beyond']} beyond noise, "
                             f"{c['missed_beyond']} missed beyond noise)")
            lines.append(f"| {md_escape(t.title)} | " + " | ".join(cells) + " |")
        lines.append("")
        for role in roles:
            exps = sorted({r.experiment for r in self.rows if r.role == role})
            lines.append(f"## {ROLE_TITLES[role]}: " + ", ".join(
                md_escape(e) + (f" (holds out from {md_escape(self.roles[e][1])})" if self.roles[e][1] else "")
                for e in exps))
            lines.append("")
            heads = ["row", "experiment", "D1 / D2"] + [t.heading for t in targets]
            lines += ["| " + " | ".join(heads) + " |", "|" + "---|" * len(heads)]
            for row in (x for x in self.rows if x.role == role):
                d1d2 = f"{_num(row.means.get('d1'))} / {_num(row.means.get('d2'))}"
                cells = [md_escape(row.label), md_escape(row.experiment), d1d2]
                cells += [md_escape(_margin_cell(row.margins[t.key])) if t.key in row.margins else "–"
                          for t in targets]
                lines.append("| " + " | ".join(cells) + " |")
            lines.append("")
            for t in targets:
                lines.append(f"- {md_escape(self.count_line(role, t))}")
            for t in targets:
                seeds = self.seed_line(role, t)
                if seeds:
                    lines.append(f"- {md_escape(seeds)}")
            reach = self.out_of_reach_line(role)
            if reach:
                lines.append(f"- {md_escape(reach)}")
            lines.append("")
        lines += ["Each margin: mean of the paired differences d over (seed, frame) pairs, oriented so that "
                  "d > 0 is better for the method, [bootstrap 95% interval, resampling whole seeds with their frames], "
                  "the method it is measured "
                  "against, n pairs, of k seeds (damages, where a row has more than one) those whose own mean "
                  "of d meets the threshold, and the verdict against the target's threshold (met / missed: the interval "
                  f"is on that side of it and the Wilcoxon signed-rank p of d − threshold <= {stats.ALPHA}; "
                  f"within noise otherwise; n too small below n = {stats.min_pairs(1)}). D1, D2 and NSHD are "
                  "whole-frame values at the intrinsic peak; temporal consistency is one value per seed, in the "
                  "holes" + ("; colour is cpsnr_y (pc_error's BT.709 Y) in the holes, on the rows whose sequence "
                             "carries colour (– elsewhere)" if COLOUR_TARGETS[0] in targets else "") + ".", ""]
        lines += [f"- {md_escape(n)}" for n in self.notes]
        return "\n".join(lines).rstrip() + "\n"

    def csv(self) -> str:
        targets = self.targets()
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(["role", "experiment", "holds_out", "row", "method", "target", "metric", "scope", "peak",
                         "against", "method_mean", "against_mean", "margin", "low", "high", "n", "threshold",
                         "p_value", "met", "verdict", "seeds", "seeds_met"])
        for r in self.rows:
            for t in targets:
                if t.key not in r.margins:
                    continue
                m = r.margins[t.key]
                writer.writerow([r.role, csv_safe(r.experiment), csv_safe(self.roles[r.experiment][1] or ""),
                                 csv_safe(r.label), csv_safe(r.method), t.key, t.metric, t.scope, t.peak,
                                 csv_safe(m.against or ""), _g(m.method_mean), _g(m.against_mean), _g(m.margin),
                                 _g(m.low), _g(m.high), m.n, t.threshold, _g(m.p_value), m.met, m.verdict,
                                 m.seeds, m.seeds_met])
        return buf.getvalue()


def _g(x) -> str:
    return "" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x + 0.0:.6g}"  # no "-0"


def _num(x, digits: int = 2, sign: bool = False) -> str:
    if x is None or not math.isfinite(x):
        return "–"
    return f"{x:+.{digits}f}" if sign else f"{x:.{digits}f}"


def _margin_cell(m: Margin) -> str:
    if not m.defined:
        return "–"
    # dB: two decimals; other scales (NSHD ~1e-8): 3 significant digits
    if m.target.metric.startswith(("gpsnr", "cpsnr")):
        def show(x):
            return _num(x, 2, True)
    else:
        def show(x):
            return f"{x:+.3g}"
    interval = "" if math.isnan(m.low) else f" [{show(m.low)}, {show(m.high)}]"
    seeds = f", {m.seeds_met} of {m.seeds} seeds" if m.seeds > 1 else ""
    return f"{show(m.margin)}{interval} vs {m.against}, n {m.n}{seeds}: {m.verdict}"


# -- the computation ---------------------------------------------------------------------------
def _pairs(df: pd.DataFrame) -> dict[str, dict]:
    """method -> {(seed, frame): value} (finite values only)."""
    out: dict[str, dict] = {}
    for method, seed, frame, value in zip(df["method"], df["seed"], df["frame"], df["value"]):
        if value is not None and math.isfinite(float(value)):
            out.setdefault(method, {})[(int(seed), int(frame))] = float(value)
    return out


def margin(obs: dict[str, dict], method: str, target: Target) -> Margin:
    """The method's margin on one target from ``obs`` (method -> {(seed, frame): value})."""
    sign = 1.0 if target.higher_is_better else -1.0
    nan = math.nan
    mine = obs.get(method, {})
    if not mine:
        return Margin(target, None, nan, nan, nan, nan, nan, 0, nan)
    own = float(np.mean(list(mine.values())))
    if target.against == "floor":
        against = FLOOR if obs.get(FLOOR) and method != FLOOR else None
    else:
        others = {m: float(np.mean(list(v.values()))) for m, v in obs.items() if m != method and v}
        against = max(others, key=lambda m: sign * others[m]) if others else None
    if against is None:
        return Margin(target, None, own, nan, nan, nan, nan, 0, nan)
    keys = sorted(set(mine) & set(obs[against]))
    d = np.array([sign * (mine[k] - obs[against][k]) for k in keys])
    theirs = float(np.mean(list(obs[against].values())))
    if not len(d):
        return Margin(target, against, own, theirs, nan, nan, nan, 0, nan)
    # per seed (one damage of the row): the interval resamples whole damages, and a row's mean can meet the
    # target while some of its damages miss it
    seed_of = np.array([seed for seed, _ in keys])
    low, high = stats.mean_difference_interval(d, groups=seed_of)
    seed_means = [float(d[seed_of == seed].mean()) for seed in np.unique(seed_of)]
    return Margin(target, against, own, theirs, float(d.mean()), low, high, len(d),
                  stats.signed_rank_p(d - target.threshold), len(seed_means),
                  sum(x >= target.threshold for x in seed_means))


def compute_margins(obs: pd.DataFrame, method: str, roles: dict[str, tuple[str, str | None]],
                    notes: list[str] | None = None) -> MarginReport:
    """The margins of ``method`` on every row of ``obs`` (columns `OBS_COLUMNS`: one value per
    experiment, row identity, method label, seed, frame, metric, scope, peak).

    roles: experiment -> (role, holds_out); an experiment it lacks is "unmarked".
    """
    missing = sorted(set(OBS_COLUMNS) - set(obs.columns))
    if missing:
        raise UserError(f"observations lack the columns {missing}")
    rows = []
    for (experiment, row), block in obs.groupby(["experiment", "row"], sort=False):
        if method not in set(block["method"]):
            continue
        role = roles.get(experiment, ("unmarked", None))[0]
        result = MarginRow(experiment, role, row, str(block["row_label"].iloc[0]), method)
        is_oracle = block["method"].astype(str).str.startswith(ORACLE_PREFIX)
        methods, oracles = block[~is_oracle], block[is_oracle]
        for t in TARGETS:
            sub = methods[(methods["metric"] == t.metric) & (methods["scope"] == t.scope)
                          & (methods["peak"] == t.peak)]
            result.margins[t.key] = margin(_pairs(sub), method, t)
            if t.key in ("d1", "d2"):
                result.means[t.key] = result.margins[t.key].method_mean
        for t in COLOUR_TARGETS:  # only where the method's runs of this row scored colour
            sub = methods[(methods["metric"] == t.metric) & (methods["scope"] == t.scope)
                          & (methods["peak"] == t.peak)]
            if (sub["method"] == method).any():
                result.margins[t.key] = margin(_pairs(sub), method, t)
        oracle_label = ORACLE_PREFIX + MARGIN_ORACLE
        if (oracles["method"] == oracle_label).any():
            for t in ORACLE_TARGETS:
                keep = (block["metric"] == t.metric) & (block["scope"] == t.scope) & (block["peak"] == t.peak)
                sub = block[keep & (~is_oracle | (block["method"] == oracle_label)) & (block["method"] != method)]
                result.margins[t.key] = margin(_pairs(sub), oracle_label, t)
        rows.append(result)
    if not rows:
        raise UserError(f"no row holds results of {method!r}; check --method and --experiments")
    order = {r: i for i, r in enumerate(ROLES)}
    rows.sort(key=lambda r: (order.get(r.role, len(order)), r.experiment, r.label))
    return MarginReport(method, rows, {e: roles.get(e, ("unmarked", None)) for e in {r.experiment for r in rows}},
                        list(notes or []))


# -- from a results store ----------------------------------------------------------------------
def _canonical(value) -> str:
    return sorted_json(value, stringify=True)


def _holes_label(holes: dict) -> str:
    if holes.get("label"):
        return str(holes["label"])
    params = ", ".join(f"{k}={v}" for k, v in sorted((holes.get("params") or {}).items()))
    return f"{holes.get('generator')}({params})" if params else str(holes.get("generator"))


def run_table(runs: pd.DataFrame) -> pd.DataFrame:
    """One row per (run, experiment) of a store's `runs_frame`: the row identity (canonical JSON of
    the spec's identity without its method and seed), its label, the method's name, parameters and
    label, the seed, the declared role and the experiment the spec was written for."""
    from dpcbench.bench.experiment.config import RunSpec

    records = []
    for run_id, experiment, spec_text, finished, output_dir, code, env_text in zip(
            runs["run_id"], runs["experiment"], runs["spec"], runs["finished_at"], runs["output_dir"],
            runs["code_version"], runs["env"]):
        spec = json.loads(spec_text) if spec_text else {}
        if not spec.get("sequence"):
            continue
        identity = RunSpec.from_dict({k: spec.get(k) for k in RunSpec.__dataclass_fields__ if k in spec}).identity()
        holes = dict(identity["holes"])
        seed = holes.pop("seed", 0)
        versions = identity["versions"]
        base = {"sequence": identity["sequence"], "holes": holes, "protocol": identity["protocol"],
                "detector": versions.get("detector")}
        row = _canonical({**base, "data": versions.get("data")})
        sequence_label = spec["sequence"].get("label") or spec["sequence"].get("name")
        records.append({"run_id": run_id, "experiment": experiment, "row": row, "row_base": _canonical(base),
                        "row_label": f"{sequence_label} · {_holes_label(spec['holes'])}",
                        "method_name": spec["method"]["name"], "method_params": _canonical(spec["method"]["params"]),
                        "method_label": spec["method"].get("label"), "seed": int(seed),
                        "declared_role": spec.get("data_role"), "declared_holds_out": spec.get("holds_out"),
                        "spec_experiment": spec.get("experiment"), "finished_at": finished or "",
                        "output_dir": output_dir if isinstance(output_dir, str) else None,
                        "sequence_spec": _canonical(spec["sequence"]),
                        "method_version": str((spec.get("versions") or {}).get("method") or "?"),
                        "code_version": code if isinstance(code, str) and code else "?",
                        "isa": env_isa(env_text)})
    return pd.DataFrame(records, columns=["run_id", "experiment", "row", "row_base", "row_label", "method_name",
                                          "method_params",
                                          "method_label", "seed", "declared_role", "declared_holds_out",
                                          "spec_experiment", "finished_at", "output_dir", "sequence_spec",
                                          "method_version", "code_version", "isa"])


def preset_roles(folder: Path = PRESETS) -> dict[str, tuple[str, str | None]]:
    """experiment name -> (data_role, holds_out) declared by the presets in ``folder``."""
    out = {}
    for path in sorted(folder.glob("*.toml")):
        try:
            exp = tomllib.loads(path.read_text()).get("experiment", {})
        except (tomllib.TOMLDecodeError, UnicodeDecodeError):
            continue
        if isinstance(exp, dict) and exp.get("name") and exp.get("data_role"):
            out[str(exp["name"])] = (str(exp["data_role"]), exp.get("holds_out"))
    return out


def resolve_roles(table: pd.DataFrame, presets: dict | None = None) -> tuple[dict, list[str]]:
    """experiment -> (role, holds_out): from the specs written for that experiment (the newest when
    they differ), else from the preset of that name, else "unmarked"; and notes saying which."""
    presets = preset_roles() if presets is None else presets
    roles, notes = {}, []
    for experiment, block in table.groupby("experiment", sort=True):
        own = block[(block["spec_experiment"] == experiment) & block["declared_role"].notna()]
        if len(own):
            newest = own.sort_values("finished_at").iloc[-1]
            holds_out = newest["declared_holds_out"]
            roles[experiment] = (newest["declared_role"], holds_out if isinstance(holds_out, str) and holds_out else None)
        elif experiment in presets:
            roles[experiment] = presets[experiment]
            notes.append(f"{experiment}: its runs record no data role (stored before the key existed, or run by "
                         f"another experiment); the role {presets[experiment][0]} is the preset's")
        else:
            roles[experiment] = ("unmarked", None)
            notes.append(f"{experiment}: no data role declared (experiment.data_role); listed as unmarked")
    return roles, notes


def versions_note(table: pd.DataFrame, method: str) -> str:
    """Which code versions the runs read come from (the run table after the newest run of each cell is kept):
    each method's version, with run counts where a method's runs mix versions, the measured ``method`` first."""
    parts = []
    by_method = table.groupby("method", sort=True)["method_version"]
    for name in sorted(by_method.groups, key=lambda m: (m != method, m)):
        counts = by_method.get_group(name).value_counts()
        if len(counts) == 1:
            parts.append(f"{name} {counts.index[0]}")
        else:
            mix = ", ".join(f"{v} on {n} runs" for v, n in sorted(counts.items(), key=lambda x: -x[1]))
            parts.append(f"{name} MIXED ({mix}: rows run at different code versions; rerun the older ones)")
    return "method versions read (the newest run of each cell): " + "; ".join(parts)


def heldout_check(table: pd.DataFrame, roles: dict) -> list[str]:
    """A note per held-out experiment: the damaged inputs (row, seed) it shares with the experiment
    it holds out from (0 when it is held out), or that experiment's absence from the store."""
    notes = []
    inputs = {e: set(zip(b["row"], b["seed"])) for e, b in table.groupby("experiment")}
    for experiment, (role, holds_out) in sorted(roles.items()):
        if role != "heldout" or not holds_out:
            continue
        if holds_out not in inputs:
            notes.append(f"held-out check: {experiment} holds out from {holds_out}, which is not among the "
                         "experiments read, so its inputs were not compared")
            continue
        shared = inputs[experiment] & inputs[holds_out]
        verdict = "held out" if not shared else "NOT held out: the same damaged data was tuned on"
        notes.append(f"held-out check: {experiment} shares {len(shared)} of {len(inputs[experiment])} damaged inputs "
                     f"(data, damage, seed) with {holds_out}: {verdict}")
    return notes


def newest_data(table: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """(the run table without the runs of superseded data, a note per row it drops runs from): of the rows of one
    experiment that differ only in their data version (the sequence's files were edited or replaced between two
    runs of it, or the older runs predate content fingerprints), the row of the newest run is kept. Both would
    otherwise be listed under one label, each with the methods that happened to run on that version of the data."""
    if table.empty:
        return table, []
    newest = (table.sort_values("finished_at", kind="stable").groupby(["experiment", "row_base"], sort=False)["row"]
              .last().rename("newest_row"))
    merged = table.join(newest, on=["experiment", "row_base"])
    stale = merged["row"] != merged["newest_row"]
    notes = [f"{experiment} · {label}: {len(group)} run(s) on an older version of the sequence's data left out "
             f"(its files changed since; rerun the experiment to compute them on the current data)"
             for (experiment, label), group in merged[stale].groupby(["experiment", "row_label"], sort=True)]
    return table[~stale.to_numpy()], notes


def store_observations(results: pd.DataFrame, runs: pd.DataFrame, experiments: list[str] | None = None):
    """(observations with `OBS_COLUMNS`, the run table, notes) from a store's `results_frame` and
    `runs_frame`; the newest run of each (experiment, row, seed, method configuration), on the newest data
    (`newest_data`)."""
    from dpcbench.bench.reporting.tables import config_labels

    table = run_table(runs)
    if experiments is not None:
        table = table[table["experiment"].isin(experiments)]
    if table.empty:
        raise UserError("no finished run in the experiments read; run them first (dpcbench run CONFIG)")
    table, notes = newest_data(table)
    cell = ["experiment", "row", "seed", "method_name", "method_params"]
    table = table.sort_values("finished_at", kind="stable").groupby(cell, sort=False).tail(1)
    given = {(n, p): lab for n, p, lab in zip(table["method_name"], table["method_params"], table["method_label"])
             if isinstance(lab, str) and lab}
    table = table.assign(method=config_labels(table["method_name"], table["method_params"], given=given).to_numpy())
    keep = table[["run_id", "experiment", "row", "row_label", "method", "seed"]]
    df = results.merge(keep, on=["run_id", "experiment"], how="inner", suffixes=("_store", ""))
    df = df.assign(peak=df["peak"].fillna("").astype(str))
    return df[OBS_COLUMNS], table, notes


def oracle_observations(table: pd.DataFrame, method: str) -> tuple[pd.DataFrame, list[str]]:
    """The smooth-surface oracle (`bench.results.oracle`, variant `MARGIN_ORACLE`) scored like a method on the
    damaged frames of every (experiment, row, seed) where ``method`` ran: whole-frame D1, D2 (intrinsic peak, the truth's own
    normals where it has them, as the runs are scored) and NSHD, as observations labelled
    ``ORACLE_PREFIX + MARGIN_ORACLE``; and notes on cells whose run folder is gone. Frame f of seed s is
    sampled with seed f."""
    from dpcbench.bench.data.datasets import load_run_sequence
    from dpcbench.bench.execution.provenance import read_run_folder
    from dpcbench.bench.results.oracle import score_oracles

    records, notes, truths = [], [], {}
    cells = table[table["method"] == method][["experiment", "row", "seed"]].drop_duplicates()
    for experiment, row, seed in cells.itertuples(index=False):
        cell = table[(table["experiment"] == experiment) & (table["row"] == row) & (table["seed"] == seed)]
        cell = cell.sort_values("method_name", key=lambda m: m != FLOOR, kind="stable")  # the floor's run first
        folder = next((Path(d) for d in cell["output_dir"] if d and (Path(d) / "manifest.json").is_file()), None)
        label = cell["row_label"].iloc[0]
        if folder is None:
            notes.append(f"oracle: {experiment} · {label} · seed {seed}: no run folder left with its damaged frames; "
                         "not scored")
            continue
        key = cell["sequence_spec"].iloc[0]
        if key not in truths:
            truths[key] = load_run_sequence(json.loads(key))
        truth = truths[key]
        damaged = read_run_folder(folder)["damaged"]
        normals = [f.normals for f in truth.frames]
        scores = score_oracles(truth.points, damaged, [MARGIN_ORACLE],
                               reference_normals=normals if any(n is not None for n in normals) else None)
        for f, values in enumerate(scores[MARGIN_ORACLE]["frame"]["frames"]):
            for metric in ("gpsnr_d1", "gpsnr_d2", "nshd"):
                records.append({"experiment": experiment, "row": row, "row_label": label,
                                "method": ORACLE_PREFIX + MARGIN_ORACLE, "seed": int(seed), "frame": f, "metric": metric,
                                "scope": "frame", "peak": "intrinsic" if metric.startswith("gpsnr") else "",
                                "value": values.get(metric, math.nan)})
    return pd.DataFrame(records, columns=OBS_COLUMNS), notes


def margins_from_store(store, method: str, experiments: list[str] | None = None, *,
                       oracle: bool = False) -> MarginReport:
    """`compute_margins` of ``method`` over the experiments of a `bench.results.store.ResultsStore` (default:
    every experiment that holds a run of the method); ``oracle``: with the smooth-surface oracle's margins
    (`oracle_observations`: every row's sequence is loaded and scored once more)."""
    known = store.experiments()
    if experiments:
        unknown = [e for e in experiments if e not in known]
        if unknown:
            raise UserError(f"--experiments: no experiment {unknown[0]!r} in {store.path}; it holds: "
                            f"{', '.join(known) or 'none'}")
    results, runs = store.results_frame(), store.runs_frame()
    runs = runs[runs["status"] == "done"]
    obs, table, data_notes = store_observations(results, runs, experiments or None)
    if not experiments:
        with_method = set(table.loc[(table["method_name"] == method) | (table["method"] == method), "experiment"])
        if not with_method:
            raise UserError(f"no experiment in {store.path} holds a run of {method!r}; known methods there: "
                            f"{', '.join(sorted(set(table['method_name'])))}")
        obs = obs[obs["experiment"].isin(with_method)]
        table = table[table["experiment"].isin(with_method)]
    labels = sorted(set(table.loc[table["method_name"] == method, "method"]))
    if method not in set(table["method"]) and len(labels) > 1:
        raise UserError(f"--method {method}: the store holds {len(labels)} configurations of it ({', '.join(labels)}); "
                        "give one of these labels as --method")
    label = method if method in set(table["method"]) or not labels else labels[0]
    roles, notes = resolve_roles(table)
    notes += data_notes + [versions_note(table, label)] + computed_with_notes(table) + heldout_check(table, roles)
    if oracle:
        extra, oracle_notes = oracle_observations(table, label)
        obs = pd.concat([obs, extra], ignore_index=True)
        notes += oracle_notes
    return compute_margins(obs, label, roles, notes)
