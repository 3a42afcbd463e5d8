"""The screen's choice of what OpenFAST confirms (wtftc.campaign.scorecard.screen): the
scenarios that decide a group's verdicts, on rows whose answer is known."""

from wtftc.campaign.scorecard import screen
from wtftc.campaign.scorecard.scored import METRICS
from wtftc.campaign.sweep import confirm

KEYS = [k for k, *_ in METRICS["normal_production"]]


def row(controller, wind, seed, status="ok", cause=None, peak=1.05, fault="none",
        target=None, **values):
    """A sweep row with what the chooser and the outcome rules read; every metric 1
    unless given."""
    return {"controller": controller, "mean_wind_mps": wind, "turbulence_class": "B",
            "seed": seed, "fault_type": fault, "runaway_target_deg": target,
            "onset_s": None if fault == "none" else 40.0, "status": status, "cause": cause,
            "diverged_at_s": None if status == "ok" else 50.0,
            "overspeed_peak_over_rated": peak, "overspeed_peak_over_rated_after_onset":
            None if fault == "none" else peak, "speed_min_over_rated_after_onset": None,
            "transient_s": 30.0, **{k: 1.0 for k in KEYS}, **values}


def grid(ratios):
    """Two columns over winds × seeds, the controller's metric ``ratios[(wind, seed)]``
    times the baseline's."""
    rows = []
    for (wind, seed), x in ratios.items():
        rows.append(row("pi", wind, seed))
        rows.append(row("aftc", wind, seed, rms_speed_error_own_above_rated_rad_s=x))
    return rows


def test_each_metric_sends_its_end_against_the_ratio_then_the_one_for_it():
    ratios = {(w, s): 0.8 for w in (8.0, 12.0, 16.0) for s in range(4)}
    ratios[(12.0, 2)] = 1.3  # the scenario most against "better"
    ratios[(16.0, 1)] = 0.5  # the one most for it
    rows = grid(ratios)
    by = {confirm.scenario(r): (r["mean_wind_mps"], r["seed"]) for r in rows}
    chosen = screen.decisive(rows, 1, 1.2, "normal_production", "aftc", "pi")
    why = {by[k]: w for k, w in chosen}
    assert "#1 against" in why[(12.0, 2)] and "(1.3)" in why[(12.0, 2)]
    # every other metric is 1 everywhere: one scenario each at most, before any for-end
    assert len(chosen) <= len(KEYS) and (16.0, 1) not in why
    more = screen.decisive(rows, len(KEYS) + 1, 1.2, "normal_production", "aftc", "pi")
    why = {by[k]: w for k, w in more}
    assert "#1 for" in why[(16.0, 1)] and "(0.5)" in why[(16.0, 1)]


def test_a_worse_controller_is_argued_against_by_its_best_scenario():
    ratios = {(w, s): 1.2 for w in (8.0, 12.0) for s in range(4)}
    ratios[(8.0, 3)] = 0.7
    chosen = screen.decisive(grid(ratios), 1, 1.2, "normal_production", "aftc", "pi")
    first = next(why for _, why in chosen if why.startswith("RMS"))
    assert "#1 against" in first and "0.7" in first


def test_at_least_n_are_chosen_where_the_group_has_them():
    ratios = {(w, s): 0.9 + 0.01 * s + 0.001 * w for w in (8.0, 12.0, 16.0)
              for s in range(6)}
    for n in (1, 5, 12, 18, 40):
        chosen = screen.decisive(grid(ratios), n, 1.2, "normal_production", "aftc", "pi")
        assert len(chosen) >= min(n, len(ratios))
        assert len({k for k, _ in chosen}) == len(chosen)


def test_outcomes_that_differ_come_first_and_a_fault_lost_by_both_once():
    rows = []
    for seed in range(3):
        for c in ("aftc", "rosco"):
            rows.append(row(c, 16.0, seed, fault="runaway", target=90.0,
                            peak=1.3 + 0.01 * seed))  # tripped by both
        rows.append(row("aftc", 12.0, seed, fault="lock", peak=1.1))
        rows.append(row("rosco", 12.0, seed, fault="lock", peak=1.25 if seed == 1 else 1.1))
    chosen = screen.decisive(rows, 1, 1.2, "actuator_faults", "aftc", "rosco")
    first_key, first_why = chosen[0]
    assert first_key[0] == "lock" and "controller held, baseline tripped" in first_why
    assert sum("controller held" in why for _, why in chosen) == 1
    feather = [(k, why) for k, why in chosen if k[0] == "runaway_feather"]
    assert len(feather) == 1 and "tripped by both" in feather[0][1]
    assert feather[0][0][confirm.AXES.index("seed") + 2] == 2  # the highest peak


def test_a_metric_without_values_sends_nothing():
    rows = grid({(8.0, 0): 0.9, (12.0, 0): 0.95})
    for r in rows:
        r["blade_root_flap_del_1hz_Nm"] = None  # wtftc's plant has no blade flap
    ends = screen._ends(screen._by_scenario(rows, "aftc", "pi"), 1.2,
                        ("blade_root_flap_del_1hz_Nm", "blade", "N m", True))
    assert ends == []
    chosen = screen.decisive(rows, 1, 1.2, "normal_production", "aftc", "pi")
    assert not any(why.startswith("blade") for _, why in chosen)


def test_the_confirmation_compares_both_engines_over_the_scenarios_both_held():
    """A scenario OpenFAST lost (the controller tripped there) but the screen held leaves
    both engines' ratios: the screen's is over the same three scenarios as OpenFAST's.
    The blade root, which the screen has not, is OpenFAST's alone."""
    from wtftc.campaign.scorecard import report

    key, blade = "rms_speed_error_own_above_rated_rad_s", "blade_root_flap_del_1hz_Nm"
    screen_rows, of_rows = [], []
    for seed, (on_screen, in_openfast) in enumerate([(0.9, 0.8), (0.9, 0.8), (0.9, 0.8),
                                                     (3.0, None)]):
        for rows, x, plant in ((screen_rows, on_screen, "tower_edge"),
                               (of_rows, in_openfast, "openfast")):
            lost = x is None
            rows.append(row("pi", 16.0, seed, plant=plant, **{blade: None if plant ==
                                                               "tower_edge" else 1.0}))
            rows.append(row("aftc", 16.0, seed, plant=plant, peak=1.5 if lost else 1.05,
                            **{key: 1.0 if lost else x,
                               blade: None if plant == "tower_edge" else 1.1}))
    got = report._confirmed(screen_rows, of_rows, "normal_production", "aftc", "pi", 1.2)
    m = {r["metric"]: r for r in got["metrics"]}
    assert m[key]["n_pairs"] == 3 and abs(m[key]["ratio"] - 0.8) < 1e-12
    assert abs(m[key]["screen_ratio"] - 0.9) < 1e-12  # not pulled by the lost seed's 3.0
    assert m[blade]["screen_ratio"] is None and abs(m[blade]["ratio"] - 1.1) < 1e-12
    assert m[blade]["agree"] is None
    assert got["counts"]["both_held"] == 3
