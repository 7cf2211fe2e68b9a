"""The held-out discipline: data roles in experiment configs, `dpcbench margins`, the oracle fill."""

from __future__ import annotations

from pathlib import Path

import pytest

from dpcbench.bench.experiment.config import ConfigError, load_config, parse_config
from tests import runner_fixtures as helpers

PRESETS = Path(__file__).resolve().parents[1] / "bench" / "presets"


@pytest.fixture
def seq_dir(tmp_path, monkeypatch):
    helpers.register(monkeypatch)
    return helpers.write_sequence(tmp_path / "seq", n_frames=2, n_points=200)


def _config(seq_dir, **experiment):
    return {
        "experiment": {"name": "t", "timeout_s": 60, **experiment},
        "sequences": [{"path": str(seq_dir), "frames": 2}],
        "holes": [{"generator": "test-ball", "params": {"radius": 0.2}, "seeds": [0]}],
        "methods": [{"name": "test-identity"}],
        "metrics": {"names": ["gpsnr_d1"], "peaks": ["intrinsic"], "scopes": ["frame"]},
    }


# -- the config key ------------------------------------------------------------------------------
def test_data_role_is_parsed_recorded_and_not_hashed(seq_dir):
    plain = parse_config(_config(seq_dir)).expand()
    tuning = parse_config(_config(seq_dir, data_role="tuning")).expand()
    heldout = parse_config(_config(seq_dir, data_role="heldout", holds_out="tune")).expand()
    assert [r.data_role for r in plain] == [None]
    assert [(r.data_role, r.holds_out) for r in tuning] == [("tuning", None)]
    assert [(r.data_role, r.holds_out) for r in heldout] == [("heldout", "tune")]
    # the role is recorded in the spec a run stores, and never changes an id (cached runs stay cached)
    assert heldout[0].to_dict()["data_role"] == "heldout" and heldout[0].to_dict()["holds_out"] == "tune"
    assert plain[0].run_id == tuning[0].run_id == heldout[0].run_id


@pytest.mark.parametrize("experiment, message", [
    ({"data_role": "validation"}, "experiment.data_role: expected one of tuning, heldout, got 'validation'"),
    ({"data_role": "heldout"}, "experiment.holds_out: a held-out experiment names the tuning experiment"),
    ({"data_role": "heldout", "holds_out": "t"}, "experiment.holds_out: a held-out experiment names"),
    ({"data_role": "tuning", "holds_out": "x"}, "experiment.holds_out: only with data_role = \"heldout\""),
    ({"holds_out": "x"}, "experiment.holds_out: only with data_role"),
])
def test_bad_data_role_is_refused_in_one_line(seq_dir, experiment, message):
    with pytest.raises(ConfigError) as err:
        parse_config(_config(seq_dir, **experiment))
    assert str(err.value).startswith(message) and "\n" not in str(err.value)


def test_every_fusion_preset_declares_its_role():
    roles = {}
    for path in sorted(PRESETS.glob("temporal-fusion-*.toml")):
        cfg = load_config(path)
        roles[cfg.name] = (cfg.data_role, cfg.holds_out)
    assert roles.pop("fusion-targets") == ("tuning", None)
    assert roles and all(role == ("heldout", "fusion-targets") for role in roles.values()), roles


def test_unknown_role_on_the_command_line_exits_2(tmp_path, seq_dir, capsys):
    from dpcbench.bench.cli import main

    config = tmp_path / "c.toml"
    config.write_text(f'[experiment]\nname = "t"\ndata_role = "train"\n[[sequences]]\npath = "{seq_dir}"\n'
                      '[[holes]]\ngenerator = "test-ball"\n[[methods]]\nname = "test-identity"\n')
    assert main(["run", str(config), "--dry-run", "--store", str(tmp_path / "s.sqlite")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "experiment.data_role: expected one of tuning, heldout" in err


# -- the margins computation on a hand-made results frame -----------------------------------------
def _obs(experiment, row, label, method, values, metric="gpsnr_d1", scope="frame", peak="intrinsic"):
    """Observation rows: values[seed][frame] of one method on one metric."""
    return [{"experiment": experiment, "row": row, "row_label": label, "method": method, "seed": s, "frame": f,
             "metric": metric, "scope": scope, "peak": peak, "value": v}
            for s, frames in enumerate(values) for f, v in enumerate(frames)]


def _frame(rows):
    import pandas as pd

    return pd.DataFrame([r for block in rows for r in block])


def _hand_made():
    """Three rows of 2 seeds x 4 frames (n = 8): a clear win (D1 +5 dB over the best other, D2 +2 dB over
    no fill), a D1 margin of +1 +- 0.6 dB (inside the noise) and a D2 loss to the floor (-2 dB on every
    pair); TC one value per seed."""
    import numpy as np

    rng = np.random.default_rng(0)
    base = 30 + rng.normal(0, 1, (2, 4))
    jitter = np.array([[0.6, -0.6, 0.5, -0.5], [0.4, -0.4, 0.6, -0.6]])
    rows = []
    for row, label, d1_gain, d2_gain in (("win", "A | win", 5 + 0 * jitter, 2.0),
                                         ("noise", "B", 1.0 + jitter, 0.5),
                                         ("floor", "=C", 3 + 0 * jitter, -2.0)):
        rows += [_obs("tune", row, label, "fusion", base + d1_gain),
                 _obs("tune", row, label, "graph", base),
                 _obs("tune", row, label, "none", base - 4),
                 _obs("tune", row, label, "fusion", base + d2_gain, "gpsnr_d2"),
                 _obs("tune", row, label, "graph", base - 1, "gpsnr_d2"),
                 _obs("tune", row, label, "none", base, "gpsnr_d2"),
                 _obs("tune", row, label, "fusion", 0.1 + 0 * base, "nshd", peak=""),
                 _obs("tune", row, label, "graph", 0.2 + 0 * base, "nshd", peak=""),
                 _obs("tune", row, label, "none", 0.3 + 0 * base, "nshd", peak=""),
                 _obs("tune", row, label, "fusion", [[0.5], [0.6]], "temporal_consistency", "holes", ""),
                 _obs("tune", row, label, "graph", [[0.7], [0.9]], "temporal_consistency", "holes", ""),
                 _obs("tune", row, label, "none", [[1.0], [1.0]], "temporal_consistency", "holes", "")]
    # the same rows held out, with the win turned into a D1 loss to graph
    held = [dict(r, experiment="held") for r in (x for block in rows for x in block)]
    for r in held:
        if r["row"] == "win" and r["metric"] == "gpsnr_d1" and r["method"] == "graph":
            r["value"] += 10
    return _frame(rows + [held])


def test_margins_of_a_win_a_tie_and_a_loss_to_the_floor():
    import numpy as np

    from dpcbench.bench.reporting.margins import compute_margins

    report = compute_margins(_hand_made(), "fusion", {"tune": ("tuning", None), "held": ("heldout", "tune")})
    rows = {(r.experiment, r.row): r for r in report.rows}
    win, noise, floor = rows[("tune", "win")], rows[("tune", "noise")], rows[("tune", "floor")]
    # clear win: +5 dB over graph (the best other, not none) on every pair; D2 +2 over none
    assert win.margins["d1"].against == "graph" and win.margins["d1"].margin == pytest.approx(5.0)
    assert win.margins["d1"].n == 8 and win.margins["d1"].verdict == "met"
    assert (win.margins["d1"].low, win.margins["d1"].high) == pytest.approx((5.0, 5.0))
    assert win.margins["d2"].against == "none" and win.margins["d2"].margin == pytest.approx(2.0)
    assert win.margins["d2"].verdict == "met"
    # inside the noise: mean +1 (met, as the target is mean >= 1) but the interval straddles +1
    m = noise.margins["d1"]
    assert m.margin == pytest.approx(1.0 + np.mean([0.6, -0.6, 0.5, -0.5, 0.4, -0.4, 0.6, -0.6]))
    assert m.low < 1.0 < m.high and m.verdict == "met, within noise"
    # loss to the floor: D2 2 dB below no fill on every pair
    assert floor.margins["d2"].margin == pytest.approx(-2.0) and floor.margins["d2"].verdict == "missed"
    # NSHD (lower is better): best other 0.2 - 0.1; TC: one value per seed, n = 2, too few for a claim
    assert win.margins["nshd"].against == "graph" and win.margins["nshd"].margin == pytest.approx(0.1)
    tc = win.margins["tc"]
    assert tc.against == "graph" and tc.n == 2 and tc.margin == pytest.approx(0.25)
    assert tc.verdict == "met, n too small"
    # the held-out copy: graph now 5 dB above fusion on the win row
    lost = rows[("held", "win")].margins["d1"]
    assert lost.margin == pytest.approx(-5.0) and lost.verdict == "missed"
    # count lines per role, as the targets read
    d1, d2 = (t for t in report_targets() if t.key in ("d1", "d2"))
    assert report.count_line("tuning", d1) == ("D1 >= best other + 1 dB on 3 of 3 rows (2 beyond noise; "
                                               "0 missed beyond noise)")
    assert report.count_line("heldout", d1).startswith("D1 >= best other + 1 dB on 2 of 3 rows (1 beyond noise; "
                                                       "1 missed beyond noise)")
    assert report.count_line("tuning", d2).startswith("D2 at or above no fill on 2 of 3 rows (2 beyond noise; 1 missed")
    # Markdown: labels escaped; tuning and held-out side by side in the count table
    text = report.markdown()
    assert "A \\| win" in text and "| target | tuning data | held-out data |" in text
    assert "| D1 >= best other + 1 dB | 3 of 3 (2 beyond noise, 0 missed beyond noise) | 2 of 3" in text
    # CSV: a label a spreadsheet would run as a formula is quoted
    lines = report.csv().splitlines()
    assert any(line.startswith("tuning,tune,,'=C,fusion,d2,") for line in lines)


def test_colour_target_only_on_rows_that_scored_colour():
    """Issue 54's target: hole-region cpsnr_y against the best other method, on the rows whose runs scored colour;
    a row without colour shows no colour margin, and a report without any shows no colour column."""
    import pandas as pd

    from dpcbench.bench.reporting.margins import COLOUR_TARGETS, TARGETS, compute_margins

    plain = _hand_made()
    # row "win" scored colour: fusion 0.5 dB below graph in the holes' Y on every pair, none 3 dB below fusion
    base = [[20.0, 21.0, 22.0, 23.0], [20.5, 21.5, 22.5, 23.5]]
    colour = _frame([_obs("tune", "win", "A | win", m, [[v + shift for v in f] for f in base], "cpsnr_y", "holes", "")
                     for m, shift in (("fusion", 0.0), ("graph", 0.5), ("none", -3.0))])
    report = compute_margins(pd.concat([plain, colour], ignore_index=True), "fusion",
                             {"tune": ("tuning", None), "held": ("heldout", "tune")})
    rows = {(r.experiment, r.row): r for r in report.rows}
    m = rows[("tune", "win")].margins["colour"]
    assert m.against == "graph" and m.margin == pytest.approx(-0.5) and m.n == 8 and m.verdict == "missed"
    assert "colour" not in rows[("tune", "noise")].margins and "colour" not in rows[("held", "win")].margins
    assert report.targets() == TARGETS + COLOUR_TARGETS
    assert report.count_line("tuning", COLOUR_TARGETS[0]).startswith(
        "colour (cpsnr_y) in the holes the best on 0 of 1 rows (0 beyond noise; 1 missed beyond noise)")
    text = report.markdown()
    assert "| Y in the holes − best other's (dB) |" in text and "-0.50 [-0.50, -0.50] vs graph, n 8, 0 of 2 seeds: missed" in text
    # without colour anywhere: no colour column
    assert compute_margins(plain, "fusion", {"tune": ("tuning", None)}).targets() == TARGETS


def test_a_row_that_meets_a_target_on_its_mean_shows_the_seeds_that_miss_it():
    """Three seeds x 2 frames: fusion 3 dB over graph on seeds 0 and 1 and 0.5 dB under it on seed 2. The row's mean
    (+1.83 dB) meets D1 >= best other + 1 dB; seed 2 misses it on its own, and the report says so in the cell, in the
    seed-by-seed line and in the CSV."""
    import numpy as np

    from dpcbench.bench.reporting.margins import compute_margins

    base = np.array([[30.0, 31.0], [32.0, 33.0], [34.0, 35.0]])
    gain = np.array([[3.0, 3.0], [3.0, 3.0], [-0.5, -0.5]])
    obs = _frame([_obs("tune", "r", "R", "fusion", base + gain), _obs("tune", "r", "R", "graph", base),
                  _obs("tune", "r", "R", "none", base - 5)])
    report = compute_margins(obs, "fusion", {"tune": ("tuning", None)})
    m = report.rows[0].margins["d1"]
    assert m.margin == pytest.approx(11 / 6) and m.met and (m.n, m.seeds, m.seeds_met) == (6, 3, 2)
    d1 = next(t for t in report_targets() if t.key == "d1")
    assert report.seed_line("tuning", d1) == ("D1 >= best other + 1 dB, seed by seed: 1 of the 1 rows that meet it on "
                                              "the mean have a seed that misses it on its own (1 such seeds)")
    text = report.markdown()
    assert "vs graph, n 6, 2 of 3 seeds: met" in text and "seed by seed: 1 of the 1 rows" in text
    header, *lines = report.csv().splitlines()
    assert header.endswith(",seeds,seeds_met")
    assert any(line.startswith("tuning,tune,,R,fusion,d1,") and line.endswith(",3,2") for line in lines)
    # one seed per row: no seed-by-seed line, no seeds in the cell
    single = compute_margins(_frame([_obs("tune", "r", "R", "fusion", base[:1] + 3), _obs("tune", "r", "R", "graph",
                                                                                          base[:1])]),
                             "fusion", {"tune": ("tuning", None)})
    assert single.seed_line("tuning", d1) is None and " seeds:" not in single.markdown()
    # no row meets D2 here (no D2 values at all): no D2 line
    assert report.seed_line("tuning", next(t for t in report_targets() if t.key == "d2")) is None



def test_a_margin_resamples_whole_damages_so_one_damage_that_misses_keeps_it_within_noise():
    """Three seeds x 10 frames: fusion 4 dB over graph on seeds 0 and 1, 0.5 dB on seed 2, each frame within 0.1 dB
    of its seed's gain. Read as 30 independent pairs the D1 margin (+2.83) is met beyond noise; its frames are
    not 30 damages, and the interval over whole damages reaches below the +1 dB threshold."""
    import numpy as np

    from dpcbench.bench.reporting.margins import compute_margins
    from dpcbench.bench.results import stats

    rng = np.random.default_rng(2)
    base = 30 + rng.normal(0, 1, (3, 10))
    gain = np.array([[4.0], [4.0], [0.5]]) + rng.normal(0, 0.1, (3, 10))
    obs = _frame([_obs("tune", "r", "R", "fusion", base + gain), _obs("tune", "r", "R", "graph", base)])
    m = compute_margins(obs, "fusion", {"tune": ("tuning", None)}).rows[0].margins["d1"]
    pairs_low, _ = stats.mean_difference_interval(gain.ravel())
    assert pairs_low > 1.0 and m.p_value <= stats.ALPHA  # the pairs alone would call it met beyond noise
    assert m.margin == pytest.approx(gain.mean()) and m.low < 1.0 < m.high
    assert (m.seeds, m.seeds_met) == (3, 2) and m.verdict == "met, within noise"

def report_targets():
    from dpcbench.bench.reporting.margins import TARGETS

    return TARGETS


def test_rows_are_identities_not_labels_and_the_heldout_check():
    import pandas as pd

    from dpcbench.bench.reporting.margins import compute_margins, heldout_check

    obs = _hand_made()
    obs = obs[obs["experiment"] == "tune"]
    same_label = obs.assign(row_label="one label")
    report = compute_margins(same_label, "fusion", {})
    assert len(report.rows) == 3 and {r.role for r in report.rows} == {"unmarked"}
    table = pd.DataFrame({"experiment": ["tune", "tune", "held", "held"], "row": ["a", "a", "a", "b"],
                          "seed": [0, 1, 1, 0]})
    roles = {"tune": ("tuning", None), "held": ("heldout", "tune")}
    assert heldout_check(table, roles) == ["held-out check: held shares 1 of 2 damaged inputs (data, damage, seed) "
                                          "with tune: NOT held out: the same damaged data was tuned on"]
    assert "not among the experiments read" in heldout_check(table[table["experiment"] == "held"], roles)[0]


# -- the command end to end on a tiny store -----------------------------------------------------------
def _tiny_config(path, seq_dir, name, role, seeds):
    holds = '\nholds_out = "tiny-tune"' if role == "heldout" else ""
    path.write_text(f"""[experiment]
name = "{name}"
data_role = "{role}"{holds}
[[sequences]]
path = "{seq_dir}"
frames = 3
label = "sphere | tiny"
[[holes]]
generator = "test-ball"
params = {{ radius = 0.4 }}
seeds = {seeds}
label = "ball holes"
[[methods]]
name = "test-identity"
label = "exact"
[[methods]]
name = "test-identity"
params = {{ shift = 0.02 }}
label = "shifted"
[[methods]]
name = "none"
[metrics]
names = ["gpsnr_d1", "gpsnr_d2", "nshd"]
scopes = ["frame", "holes"]
temporal_consistency = true
""")
    return path


def test_margins_command_on_a_tiny_store(tmp_path, monkeypatch, capsys):
    from dpcbench.bench.cli import main

    helpers.register(monkeypatch)
    seq_dir = helpers.write_sequence(tmp_path / "seq", n_frames=3, n_points=300)
    store = tmp_path / "s.sqlite"
    for name, role, seeds in (("tiny-tune", "tuning", "[0, 1]"), ("tiny-held", "heldout", "[5, 6]")):
        config = _tiny_config(tmp_path / f"{name}.toml", seq_dir, name, role, seeds)
        assert main(["run", str(config), "--store", str(store), "--jobs", "2", "--quiet"]) == 0
    capsys.readouterr()
    out = tmp_path / "margins"
    assert main(["margins", str(store), "--method", "exact", "--oracle", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert (out / "margins.md").read_text() in text
    assert "| target | tuning data | held-out data |" in text
    assert "## held-out data: tiny-held (holds out from tiny-tune)" in text
    assert "held-out check: tiny-held shares 0 of 2 damaged inputs" in text and "held out" in text
    from dpcbench.bench.core.isa import describe

    # every run was made by a worker of this process's environment: one instruction set, read from the runs' env
    assert f"instruction sets of the runs read: {describe()} on ".replace("_", "\\_") in text
    assert "MIXED" not in text
    # "exact" returns the damaged frames: every pair equals no fill's, so D1 is 0 dB above the best other
    # (none, tied with it) and misses +1 dB on all 6 pairs (3 frames x 2 seeds) beyond noise; D2 = no fill's: met
    import csv

    rows = list(csv.DictReader((out / "margins.csv").open()))
    assert {r["role"] for r in rows} == {"tuning", "heldout"} and len(rows) == 2 * 6
    # the smooth-surface oracle, scored on each cell's damaged frames: 6 pairs against the same references
    oracle = [r for r in rows if r["target"] == "oracle_d2"]
    assert len(oracle) == 2 and all(r["against"] == "none" and r["n"] == "6" for r in oracle), oracle
    assert "smooth-surface oracle: D2 − no fill (dB)" in text
    d1 = [r for r in rows if r["target"] == "d1"]
    assert all(float(r["margin"]) == 0 and r["n"] == "6" and r["verdict"] == "missed" for r in d1), d1
    d2 = [r for r in rows if r["target"] == "d2"]
    assert all(r["against"] == "none" and float(r["margin"]) == 0 and r["verdict"] == "met, within noise"
               for r in d2), d2
    assert all(r["row"] == "sphere | tiny · ball holes" for r in rows)
    assert "sphere \\| tiny · ball holes" in text
    # a configuration of several, asked by its registry name, and an unknown experiment: one-line errors
    assert main(["margins", str(store), "--method", "test-identity"]) == 2
    assert "2 configurations of it (exact, shifted)" in capsys.readouterr().err
    assert main(["margins", str(store), "--experiments", "nope"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no experiment 'nope'" in err


# -- the oracle fill ------------------------------------------------------------------------------
def _plane_with_hole(radius: float = 6.0):
    """A 41 x 41 unit grid on z = 0 and the same with a disc of ``radius`` around its centre removed."""
    import numpy as np

    g = np.arange(41.0)
    truth = np.column_stack([np.repeat(g, 41), np.tile(g, 41), np.zeros(41 * 41)])
    mask = np.linalg.norm(truth[:, :2] - 20.0, axis=1) <= radius
    return truth, truth[~mask], mask


def test_oracle_on_a_plane_with_a_hole():
    import numpy as np

    from dpcbench.bench.results.oracle import missing_points, off_surface_rms, oracle_fill, score_oracles
    from dpcbench.metrics.scoring import DEFAULT_MAX_PSNR

    truth, damaged, mask = _plane_with_hole()
    # the missing points, found with the mask or by matching, are the removed ones
    assert np.array_equal(missing_points(truth, damaged), truth[mask])
    surface = oracle_fill(truth, damaged, "surface", mask=mask, seed=3)
    fill = surface[len(damaged):]
    assert len(fill) == mask.sum() and np.all(fill[:, 2] == 0)  # on the plane, at the truth's density
    offsets = np.abs(fill[:, :2] - truth[mask][:, :2])
    assert offsets.max() <= 0.5 and offsets.max() > 0.3  # moved within half the spacing, not left in place
    scores = score_oracles([truth], [damaged], masks=[mask], sigma=0.2)
    d1 = {v: s["frame"]["mean"]["gpsnr_d1"] for v, s in scores.items()}
    d2 = {v: s["frame"]["mean"]["gpsnr_d2"] for v, s in scores.items()}
    # closed form: every surface sample lies on the plane, so its point-to-plane error is 0: D2 at the ceiling
    assert d2["surface"] == DEFAULT_MAX_PSNR and d1["truth"] == d2["truth"] == DEFAULT_MAX_PSNR
    assert d1["none"] < d1["jitter"] and d1["none"] < d1["surface"] < d1["truth"]
    assert d2["jitter"] < DEFAULT_MAX_PSNR
    more = score_oracles([truth], [damaged], ["jitter"], masks=[mask], sigma=0.4)["jitter"]["frame"]["mean"]
    assert more["gpsnr_d2"] < d2["jitter"]
    # smooth: the surface samples on the truth's smooth surface; on a plane that is where they are already
    assert np.allclose(oracle_fill(truth, damaged, "smooth", mask=mask, seed=3), surface)
    assert d2["smooth"] == DEFAULT_MAX_PSNR
    # on a bumpy plane (each sample's own height noise) the surface samples keep the noise, the smooth ones do not
    rng = np.random.default_rng(0)
    bumpy = truth + np.column_stack([np.zeros((len(truth), 2)), rng.normal(0, 0.1, len(truth))])
    noisy = oracle_fill(bumpy, bumpy[~mask], "surface", mask=mask, seed=3)[len(damaged):]
    smooth = oracle_fill(bumpy, bumpy[~mask], "smooth", mask=mask, seed=3)[len(damaged):]
    assert np.sqrt(np.mean(smooth[:, 2] ** 2)) < 0.5 * np.sqrt(np.mean(noisy[:, 2] ** 2))
    # a method's off-surface error: its fill 0.3 above the plane
    lifted = np.vstack([damaged, truth[mask] + [0, 0, 0.3]])
    rms, count = off_surface_rms(truth, damaged, lifted)
    assert count == mask.sum() and rms == pytest.approx(0.3)


def test_refusal_oracle_keeps_exactly_the_fill_points_within_the_limit():
    import numpy as np

    from dpcbench.bench.core.errors import UserError
    from dpcbench.bench.results.oracle import refused_fill, score_refusals
    from dpcbench.metrics.scoring import DEFAULT_MAX_PSNR

    truth, damaged, mask = _plane_with_hole()  # a unit grid: one spacing is 1
    hole = truth[mask]
    on, off = hole[::2], hole[1::2] + [0.0, 0.0, 2.0]  # half the fill on the plane, half 2 spacings above it
    result = np.vstack([damaged, off[:5], on, off[5:]])
    assert np.array_equal(refused_fill(truth, damaged, result, 1.0), np.vstack([damaged, on]))  # the result's order
    assert np.array_equal(refused_fill(truth, damaged, result, 2.5), result)
    assert len(refused_fill(truth, damaged, result, 1.999)) == len(damaged) + len(on)
    scores = score_refusals([truth], [damaged], [result], [1, 2.5])
    assert list(scores) == ["method", "refusal < 1 s", "refusal < 2.5 s"]
    d2 = {label: s["frame"]["mean"]["gpsnr_d2"] for label, s in scores.items()}
    # closed form: every point kept at 1 s lies on the plane, so no point-to-plane error is left
    assert d2["refusal < 1 s"] == DEFAULT_MAX_PSNR > d2["method"] == d2["refusal < 2.5 s"]
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(UserError, match="limit"):
            refused_fill(truth, damaged, result, bad)
        with pytest.raises(UserError, match="limit"):
            score_refusals([truth], [damaged], [result], [bad])
    with pytest.raises(UserError, match="of the same sequence"):
        score_refusals([truth], [damaged], [result, result], [1])


def test_off_surface_by_depth_is_the_naive_binning_of_each_fill_point_s_offset_by_its_depth():
    """`off_surface_by_depth` against the sum written out point by point. On the unit grid (one spacing is 1) the
    first frame's missing points are lifted by 0.1 times their depth in the plane (their distance to the nearest
    damaged point), so each bin's RMS grows with its depth; the second frame's half of them lie on the plane, some on
    the bins' edges. The reference takes each fill point's offset as its height (the plane's normal is z) and its
    depth by brute force over the damaged points, and bins them by hand. The two frames pool."""
    import numpy as np

    from dpcbench.bench.core.errors import UserError
    from dpcbench.bench.results.oracle import DEPTH_EDGES, off_surface_by_depth

    truth, damaged, mask = _plane_with_hole(radius=12.0)
    hole = truth[mask]
    flat_depth = np.min(np.linalg.norm(hole[:, None, :] - damaged[None, :, :], axis=2), axis=1)
    fill = hole + np.column_stack([np.zeros((len(hole), 2)), 0.1 * flat_depth])
    result = np.vstack([damaged, fill])
    flat = hole[::2]  # the second frame's fill on the plane: off 0, depths on the bins' edges (2 and 4) included
    rows = off_surface_by_depth([truth, truth], [damaged, damaged], [result, np.vstack([damaged, flat])])
    off = np.concatenate([fill[:, 2], flat[:, 2]])
    depth = np.min(np.linalg.norm(np.vstack([fill, flat])[:, None, :] - damaged[None, :, :], axis=2), axis=1)
    assert np.isin([2.0, 4.0], depth).all()
    expected = []
    for low, high in zip(DEPTH_EDGES[:-1], DEPTH_EDGES[1:]):
        at = (depth >= low) & (depth < high)
        if at.any():
            expected.append((low, high, int(at.sum()), np.sqrt(np.mean(off[at] ** 2)), np.quantile(off[at], 0.9)))
    assert [(r["low"], r["high"], r["points"]) for r in rows] == [e[:3] for e in expected]
    assert [r["off_rms"] for r in rows] == pytest.approx([e[3] for e in expected], rel=1e-6)
    assert [r["off_p90"] for r in rows] == pytest.approx([e[4] for e in expected], rel=1e-6)
    assert len(rows) >= 3 and rows[0]["off_rms"] < rows[1]["off_rms"] < rows[-1]["off_rms"]  # deeper, farther off
    assert sum(r["points"] for r in rows) == len(fill) + len(flat)
    assert off_surface_by_depth([truth], [damaged], [damaged]) == []  # no fill point: no bin
    with pytest.raises(UserError, match="of the same sequence"):
        off_surface_by_depth([truth], [damaged], [result, result])


def test_oracle_command(tmp_path, capsys):
    import json

    import numpy as np

    from dpcbench.bench.cli import main
    from dpcbench.bench.data.sequences import save_sequence
    from dpcbench.metrics.scoring import DEFAULT_MAX_PSNR

    truth, damaged, mask = _plane_with_hole()
    save_sequence([truth, truth], tmp_path / "truth", prefix="t")
    save_sequence([damaged, damaged], tmp_path / "damaged", prefix="d")
    lifted = np.vstack([damaged, truth[mask] + [0, 0, 0.25]])
    save_sequence([lifted, lifted], tmp_path / "result", prefix="r")
    argv = ["oracle", str(tmp_path / "truth"), str(tmp_path / "damaged"), "--json"]
    assert main(argv + ["--method-result", str(tmp_path / "result")]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["sigma"] == pytest.approx(0.25, rel=1e-6)
    assert payload["measured"]["fill_points"] == 2 * mask.sum()
    assert set(payload["variants"]) == {"none", "surface", "smooth", "jitter", "truth"}
    assert payload["variants"]["surface"]["frame"]["gpsnr_d2"] == DEFAULT_MAX_PSNR
    assert main(argv[:-1] + ["--variant", "jitter"]) == 2
    assert "give its sigma with --jitter SIGMA" in capsys.readouterr().err
    # the break-even on a flat hole: no fill's D2 is the ceiling there, so it is 0
    assert main(argv + ["--variant", "none", "--break-even"]) == 0
    assert json.loads(capsys.readouterr().out)["d2_break_even"]["sigma"] == 0.0
    assert main(argv[:-1] + ["--variant", "none", "--break-even"]) == 0
    assert "D2 break-even: a complete fill within 0 units" in capsys.readouterr().out
    # the refusal oracle: the lifted fill is 0.25 spacings off, so a limit of 0.1 refuses all of it, 1 none
    assert main(argv + ["--variant", "none", "--method-result", str(tmp_path / "result"), "--refusal", "0.1,1"]) == 0
    payload = json.loads(capsys.readouterr().out)
    refusal = {label: by["frame"] for label, by in payload["refusal"].items()}
    assert list(refusal) == ["method", "refusal < 0.1 s", "refusal < 1 s"]
    assert refusal["refusal < 0.1 s"] == payload["variants"]["none"]["frame"]
    assert refusal["refusal < 1 s"] == refusal["method"] != refusal["refusal < 0.1 s"]
    assert main(argv[:-1] + ["--variant", "none", "--method-result", str(tmp_path / "result"), "--refusal", "1"]) == 0
    assert "refusal oracle:" in capsys.readouterr().out
    for bad, message in ((["--refusal", "1"], "give it with --method-result"),
                         (["--method-result", str(tmp_path / "result"), "--refusal", "0.5,x"], "'x' is no limit")):
        assert main(argv + ["--variant", "none"] + bad) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and message in err, err
    assert main(argv + ["--variant", "none", "--colour"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "has frames without colour" in err
    # by depth: the lifted fill is 0.25 off at every depth, and one point 40 above the hole's centre lies in the last
    # bin, whose open end is null in JSON
    far = np.vstack([lifted, [[20.0, 20.0, 40.0]]])
    save_sequence([far, far], tmp_path / "far", prefix="r")
    assert main(argv + ["--variant", "none", "--method-result", str(tmp_path / "far"), "--by-depth"]) == 0
    rows = json.loads(capsys.readouterr().out)["by_depth"]
    assert sum(r["points"] for r in rows) == 2 * mask.sum() + 2 and rows[0]["low"] == 0.0
    assert all(r["off_rms"] == pytest.approx(0.25, rel=1e-6) for r in rows[:-1])
    assert rows[-1] == {"low": 32.0, "high": None, "points": 2, "off_rms": pytest.approx(40.0), "off_p90": pytest.approx(40.0)}
    assert main(argv[:-1] + ["--variant", "none", "--method-result", str(tmp_path / "result"), "--by-depth"]) == 0
    assert "off RMS (s)" in capsys.readouterr().out
    assert main(argv + ["--variant", "none", "--by-depth"]) == 2
    assert "give its result with --method-result" in capsys.readouterr().err


def test_colour_oracle_reproduces_a_linear_colour_harmonically():
    """Closed form: on the unit grid a colour linear in x and y is harmonic on the 8-neighbour graph (each point's
    neighbours lie symmetrically round it), so the harmonic fill gives the hidden points their true colours: no
    error, the PSNR ceiling. The nearest input colour is a step away from them: finite, lower. The damaged points
    keep theirs, so the whole frame scores higher than the holes alone."""
    import numpy as np

    from dpcbench.bench.core.errors import UserError
    from dpcbench.bench.results.oracle import score_colour_oracles
    from dpcbench.holes.regions import HoleRegion
    from dpcbench.metrics.scoring import DEFAULT_MAX_PSNR

    truth, damaged, mask = _plane_with_hole()
    colour = np.column_stack([40 + 3 * truth[:, 0], 20 + 2 * truth[:, 1], 100 + truth[:, 0] + truth[:, 1]])
    colour = colour.astype(np.uint8)
    hole = [HoleRegion.ball([20.0, 20.0, 0.0], 6.5)]
    scores = score_colour_oracles([truth], [colour], [damaged], [colour[~mask]], masks=[mask], regions=[hole])
    harmonic, nearest = (scores[f]["holes"]["mean"] for f in ("harmonic", "nearest"))
    assert harmonic["cpsnr_y"] == harmonic["cpsnr_u"] == harmonic["cpsnr_v"] == DEFAULT_MAX_PSNR
    assert 20 < nearest["cpsnr_y"] < 60 and nearest["cpsnr_u"] < DEFAULT_MAX_PSNR
    assert scores["nearest"]["frame"]["mean"]["cpsnr_y"] > nearest["cpsnr_y"]
    with pytest.raises(UserError, match="colour oracle fill 'source'"):
        score_colour_oracles([truth], [colour], [damaged], [colour[~mask]], ["source"])


def _sphere_with_hole(radius: float = 20.0, hole: float = 6.0):
    import numpy as np

    n = 4000
    i = np.arange(n) + 0.5
    polar, azimuth = np.arccos(1.0 - 2.0 * i / n), np.pi * (1.0 + 5.0 ** 0.5) * i
    truth = radius * np.column_stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)])
    mask = np.linalg.norm(truth - [0.0, 0.0, radius], axis=1) <= hole
    return truth, truth[~mask], mask


def test_d2_break_even_brackets_no_fill_s_d2_and_is_zero_on_a_flat_hole():
    """On a sphere the jitter oracle at the break-even sigma scores no fill's D2 (within the bisection's steps):
    at half of it more, at twice less. On a plane an open hole's point-to-plane error is exactly 0 (every hidden
    point lies in its rim neighbour's tangent plane), so no jitter reaches it: sigma 0."""
    import numpy as np

    from dpcbench import metrics
    from dpcbench.bench.results.oracle import d2_break_even, oracle_fill

    truth, damaged, mask = _sphere_with_hole()
    even = d2_break_even([truth], [damaged], masks=[mask])
    sigma = even["sigma"]
    assert 0 < sigma < np.inf
    assert even["jitter_d2"] >= even["none_d2"] and even["jitter_d2"] - even["none_d2"] < 0.1

    def d2(s):
        return metrics.score_frame(truth, oracle_fill(truth, damaged, "jitter", mask=mask, sigma=s), ["gpsnr_d2"])[
            "gpsnr_d2"]

    assert d2(sigma / 2) > even["none_d2"] > d2(2 * sigma)
    flat, flat_damaged, flat_mask = _plane_with_hole()
    assert d2_break_even([flat], [flat_damaged], masks=[flat_mask])["sigma"] == 0.0


def test_a_row_out_of_reach_by_measurement():
    """The method misses D2 against no fill on the floor row; a smooth-surface oracle 1 dB below no fill on
    every pair misses it too: that row is out of reach by measurement."""
    import pandas as pd

    from dpcbench.bench.reporting.margins import ORACLE_PREFIX, compute_margins

    obs = _hand_made()
    obs = obs[obs["experiment"] == "tune"]
    none = obs[(obs["method"] == "none") & obs["metric"].isin(["gpsnr_d1", "gpsnr_d2"])]
    oracle = none.assign(method=ORACLE_PREFIX + "smooth",
                         value=none["value"] + [8.0 if m == "gpsnr_d1" else -1.0 for m in none["metric"]])
    report = compute_margins(pd.concat([obs, oracle]), "fusion", {"tune": ("tuning", None)})
    floor = next(r for r in report.rows if r.row == "floor")
    assert floor.margins["oracle_d2"].margin == pytest.approx(-1.0) and floor.margins["oracle_d2"].verdict == "missed"
    # the oracle is never "another method": the best other stays graph, and the oracle's D1 is measured
    # against the best other than the method (graph: none + 4; oracle none + 8)
    assert floor.margins["d1"].against == "graph" and floor.margins["oracle_d1"].margin == pytest.approx(4.0)
    assert report.out_of_reach_line("tuning").endswith("D1: 0 of the 0 rows that miss it; D2: 1 of the 1 rows that "
                                                       "miss it")


def test_roles_of_runs_stored_before_the_key_come_from_the_presets():
    import pandas as pd

    from dpcbench.bench.reporting.margins import preset_roles, resolve_roles

    presets = preset_roles()
    assert presets["fusion-targets"] == ("tuning", None)
    assert presets["fusion-heldout-frames"] == ("heldout", "fusion-targets")
    table = pd.DataFrame({"experiment": ["fusion-heldout", "mine", "new"], "spec_experiment": ["fusion-heldout", "mine",
                                                                                              "new"],
                          "declared_role": [None, None, "heldout"], "declared_holds_out": [None, None, "mine"],
                          "finished_at": ["a", "b", "c"]})
    roles, notes = resolve_roles(table, presets)
    assert roles == {"fusion-heldout": ("heldout", "fusion-targets"), "mine": ("unmarked", None),
                     "new": ("heldout", "mine")}
    assert any(n.startswith("fusion-heldout: its runs record no data role") for n in notes)
    assert any(n.startswith("mine: no data role declared") for n in notes)


def test_versions_note_names_each_method_s_code_version_and_flags_a_mix():
    """The report says which code versions its runs come from; runs of one method at two versions (a row rerun
    after a change, the others not) are flagged with their counts, the measured method first."""
    import pandas as pd

    from dpcbench.bench.reporting.margins import versions_note

    table = pd.DataFrame({"method": ["none", "fusion", "fusion", "lozes"], "method_version": ["1", "45", "45", "2"]})
    assert versions_note(table, "fusion").endswith("fusion 45; lozes 2; none 1")
    mixed = versions_note(table.assign(method_version=["1", "46", "45", "2"]), "fusion")
    assert "fusion MIXED (46 on 1 runs, 45 on 1 runs" in mixed and mixed.index("fusion") < mixed.index("lozes")


def test_runs_on_superseded_data_are_left_out_with_a_note():
    """A sequence whose files changed between two runs of an experiment (its data version, a stat hash, moved) gives
    two rows that differ only in their data version; one label must not list both. The row of the newest run is kept,
    the other's runs are left out with a note per row; a row with one data version, and another experiment's row on
    the old data, are kept whole."""
    import pandas as pd

    from dpcbench.bench.reporting.margins import newest_data

    table = pd.DataFrame({
        "experiment": ["tune", "tune", "tune", "tune", "tune", "other"],
        "row_base": ["A", "A", "A", "A", "B", "A"],
        "row": ["A@old", "A@old", "A@new", "A@new", "B@1", "A@old"],
        "row_label": ["samba · coherent holes"] * 4 + ["bunny · coherent holes", "samba · coherent holes"],
        "finished_at": ["2026-12-05T01", "2026-12-05T02", "2026-12-06T01", "2026-12-06T02", "2026-12-05T03",
                        "2026-12-05T04"],
    })
    kept, notes = newest_data(table)
    assert list(kept["row"]) == ["A@new", "A@new", "B@1", "A@old"]
    assert notes == ["tune · samba · coherent holes: 2 run(s) on an older version of the sequence's data left out "
                     "(its files changed since; rerun the experiment to compute them on the current data)"]
    assert newest_data(table[table["row_base"] == "B"])[1] == []
