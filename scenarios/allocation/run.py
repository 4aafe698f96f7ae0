"""Precision allocation over a motion chain, the library behind ``arfem allocate SCENARIO
--out DIR`` (:mod:`arfem.scenarios.commands.allocate`, the command, only parses and prints).

Reads an allocation scenario (:mod:`arfem.models.allocation.scenario`), solves the
NSGA-II allocation and writes, atomically:

* ``allocation.json`` -- the picked design and everything said about it, every
  quantity's unit in its name (tolerances, worst case, RSS, Monte Carlo yields,
  sensitivity ranking, convergence; for ``paper_literal`` the seed spread and Table 1)
* ``pareto.csv``      -- the Pareto front (one row per member, unit-suffixed columns)
* ``pareto.png``      -- the front with the knee (and the paper's Table 1 where it applies)
* ``convergence.png`` -- hypervolume against generations (every seed run)
* ``stackup.png``, ``sensitivity.png`` (screw formula), ``thermal.png`` (with a spindle)
* ``report.md``       -- conventions, chain, result, numbers behind every picture
* ``report.html``     -- all of the above on one self-contained page (``arfem report``)
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from arfem.io import write_csv, write_json
from arfem.models.allocation import tolerance
from arfem.models.allocation.problem import (COMPONENT_UNIT, COMPONENTS, MAX_EVALUATIONS,
                                             ROTATIONS, allocate, unit_values,
                                             with_settings, work_estimate,
                                             worst_case_over_cycle)
from arfem.models.allocation.scenario import AllocationScenario, build_chain
from arfem.params import InputError
from arfem.scenarios.allocation.file import load_allocation_scenario
from arfem.scenarios.html_report import write_html_report

__all__ = ["run_allocation", "write_allocation", "allocation_terminal_line", "WRITES",
           "CONVERGED"]

#: Okabe-Ito colours (distinguishable with the common colour-vision deficiencies)
OKABE = ["#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9", "#D55E00", "#F0E442", "#000000"]
#: Monte Carlo draws for the yield of the picked design
N_DRAWS = 100_000
#: the files ``arfem allocate`` may put into --out (checked before the work: never an input or a
#: file arfem did not write; see arfem.scenarios.outdir)
WRITES = ("pareto.csv", "allocation.json", "pareto.png", "convergence.png", "stackup.png",
          "sensitivity.png", "thermal.png", "thermal.csv", "report.md", "report.html")
#: seed offset of the report's Monte Carlo (independent of the optimiser's draws)
MC_SEED = 1_000_003
#: the converged run of the paper_literal model (the paper's own optimum)
CONVERGED = {"pop_size": 200, "n_gen": 1000, "converge": True}


def _check_work(sc: AllocationScenario, limit) -> None:
    w = work_estimate(sc.settings)
    if limit is not None and w > limit:
        raise InputError(f"{sc.settings.pop_size} x {sc.settings.n_gen} = {w:,} evaluations per "
                         f"run exceeds the limit of {limit:,} (about 2 min on 2 cores); lower "
                         f"them or pass --no-work-limit",
                         f"{sc.source}: optimizer.pop_size x optimizer.n_gen")


def _percentile_of(values, x) -> float:
    """Percent of ``values`` below ``x`` (ties count half)."""
    v = np.asarray(values, float)
    return float(100.0 * (np.sum(v < x) + 0.5 * np.sum(v == x)) / len(v))


def run_allocation(scenario_path, seeds: int | None = None, work_limit=MAX_EVALUATIONS,
                   limits=None) -> dict:
    """Everything the writers need: scenario, chain, the runs of every seed, the pick."""
    if seeds is not None and not 1 <= seeds <= 100:
        raise InputError(f"must be 1 to 100, got {seeds}", "--seeds")
    sc = load_allocation_scenario(scenario_path, limits)
    _check_work(sc, work_limit)
    chain, spindle = build_chain(sc)
    st = sc.settings
    n_seeds = seeds if seeds is not None else (20 if st.formula == "paper_literal" else 3)
    if not 1 <= n_seeds <= 100:
        raise InputError(f"must be 1 to 100, got {n_seeds}", "--seeds")
    runs = [allocate(chain, with_settings(st, seed=st.seed + s), max_evaluations=None)
            for s in range(n_seeds)]
    out = {"scenario": sc, "chain": chain, "spindle": spindle, "runs": runs, "result": runs[0]}
    if st.formula == "paper_literal":
        conv = with_settings(st, **CONVERGED)
        out["converged_runs"] = [allocate(chain, with_settings(conv, seed=st.seed + s),
                                          max_evaluations=None) for s in range(3)]
    return out


def _tol_table(chain, X) -> dict:
    V = unit_values(chain, X)[0]
    return {u.name: {f"{c}_{'um' if c not in ROTATIONS else 'urad'}": float(V[6 * i + j] * 1e3)
                     for j, c in enumerate(COMPONENTS)} for i, u in enumerate(chain.units)}


def _screw_summary(run) -> dict:
    chain, res = run["chain"], run["result"]
    st, k = res.settings, res.chosen
    X = res.front_X[k:k + 1]
    ev = res.front
    V = unit_values(chain, X)[0]
    t = V * np.tile([1, 1, 1, 1e-3, 1e-3, 1e-3], len(chain.units))    # mm, rad
    Jv, _ = chain.sensitivities()
    th = chain.thermal
    if th is None:
        Js, offs = Jv, None
    else:   # the two extreme instants of the cycle (the worst is at one of them)
        dmin, dmax = np.min(th.growth_mm), np.max(th.growth_mm)
        Js = np.concatenate([Jv, Jv])
        offs = np.concatenate([dmin * th.direction, dmax * th.direction])
    # fresh draws: not the optimiser's common random numbers (seeded by st.seed)
    yields = {d: tolerance.monte_carlo(t, Js, st.delta_E_mm, N_DRAWS, d, seed=MC_SEED + st.seed,
                                       offsets_mm=offs) for d in ("uniform", "normal")}
    sens = tolerance.sensitivity(t, Jv)
    names = chain.component_names()
    order = np.argsort(-sens["variance_share"])
    ranking = []
    for r in order:
        c = names[r].split(".")[1]
        ranking.append({"component": names[r],
                        "gain_um_per_" + ("urad" if c in ROTATIONS else "um"): float(sens["gain"][r] * (1e-3 if c in ROTATIONS else 1.0)),
                        "tolerance_" + ("urad" if c in ROTATIONS else "um"): float(V[r] * 1e3),
                        "worst_case_contribution_um": float(sens["contribution_mm"][r] * 1e3),
                        "rss_variance_share": float(sens["variance_share"][r])})
    out = {
        "tolerances": _tol_table(chain, X),
        "units_worst_case_um": {n: float(v * 1e3) for n, v in zip(chain.names, ev.unit_stack_mm[k])},
        "worst_case_um": float(ev.worst_case_mm[k] * 1e3),
        "kinematic_worst_case_um": float(ev.kinematic_worst_case_mm[k] * 1e3),
        "rss_um": float(ev.rss_mm[k] * 1e3),
        "sum_of_unit_worst_cases_um": float(np.sum(ev.unit_stack_mm[k]) * 1e3),
        "cost_rel": float(ev.cost[k]),
        "yield_uniform": yields["uniform"]["yield"], "yield_normal_3sigma": yields["normal"]["yield"],
        "monte_carlo": {d: {"yield": y["yield"], "n_draws": y["n_draws"],
                            "p99_um": y["p99_mm"] * 1e3, "max_um": y["max_mm"] * 1e3}
                        for d, y in yields.items()},
        "sensitivity_ranking": ranking,
    }
    if th is not None:
        out["thermal_series"] = _thermal_series(chain, X)
    return out


def _thermal_series(chain, X) -> dict:
    """Worst-case stack at every instant of the cycle, the picked design [mm]."""
    th = chain.thermal
    return {"times_s": th.times_s, "growth_mm": th.growth_mm,
            "worst_case_mm": worst_case_over_cycle(chain, X)}


def _paper_summary(run) -> dict:
    chain, sc = run["chain"], run["scenario"]
    ref = sc.reference_accuracy_mm or {}
    picks = np.array([r.front.unit_stack_mm[r.chosen] for r in run["runs"]])
    pooled = np.concatenate([r.front.unit_stack_mm for r in run["runs"]])
    spread = {}
    for i, n in enumerate(chain.names):
        d = {"picked_min_mm": float(picks[:, i].min()), "picked_median_mm": float(np.median(picks[:, i])),
             "picked_max_mm": float(picks[:, i].max()),
             "front_min_mm": float(pooled[:, i].min()), "front_max_mm": float(pooled[:, i].max())}
        if n in ref:
            d.update(table1_mm=ref[n], table1_percentile_of_picked=_percentile_of(picks[:, i], ref[n]),
                     table1_percentile_of_fronts=_percentile_of(pooled[:, i], ref[n]))
        spread[n] = d
    st = run["result"].settings
    out = {"seed_spread": spread, "n_seeds": len(run["runs"]),
           "picked_per_seed": [{"seed": r.settings.seed, "f1_mm": float(r.front.f1_mm[r.chosen]),
                                "cost_rel": float(r.front.cost[r.chosen]),
                                "m_E": float(r.front.m_E[r.chosen]),
                                "h_mm": {n: float(v) for n, v in zip(chain.names, r.front.unit_stack_mm[r.chosen])}}
                               for r in run["runs"]]}
    if ref:
        h = np.array([ref.get(n, np.nan) for n in chain.names])
        out["table1"] = {"h_mm": ref, "cost_rel": float(np.sum(st.a * np.exp(-h / st.b_mm))),
                         "f1_lowest_possible_mm": float(np.nanmin(h))}
    conv = []
    for r in run.get("converged_runs", []):
        ev = r.front
        conv.append({"seed": r.settings.seed, "n_gen": r.n_generations, "n_eval": r.n_evaluations,
                     "terminated_by_criteria": r.converged, "front_size": len(r.front_X),
                     "cost_min": float(ev.cost.min()), "f1_min_mm": float(ev.f1_mm.min()),
                     "f1_at_cost_min_mm": float(ev.f1_mm[np.argmin(ev.cost)]),
                     "h_at_cost_min_mm": {n: float(v) for n, v in zip(chain.names, ev.unit_stack_mm[np.argmin(ev.cost)])}})
    out["converged"] = conv
    if ref and conv:
        f1_t1 = out["table1"]["f1_lowest_possible_mm"]
        best = [float(r.front.cost[r.front.f1_mm <= f1_t1].min())
                for r in run["converged_runs"] if np.any(r.front.f1_mm <= f1_t1)]
        if best:
            out["table1"]["converged_front_cost_at_or_below_its_f1"] = min(best)
            out["table1"]["dominated_by_converged_front"] = bool(min(best) < out["table1"]["cost_rel"])
    return out


def _allocation_json(run) -> dict:
    sc, chain, res = run["scenario"], run["chain"], run["result"]
    st, k = res.settings, res.chosen
    ev = res.front
    out = {
        "scenario": sc.name, "source": str(sc.source), "formula": st.formula,
        "constraint": st.constraint if st.formula == "screw" else "m_E = |sum omega| <= delta_E",
        "feasible": bool(res.feasible), "delta_E_mm": st.delta_E_mm,
        "working_radius_mm": st.working_radius_mm, "poses": list(chain.pose_labels),
        "pick": st.pick, "front_size": int(len(res.front_X)),
        "convergence": [{"seed": r.settings.seed, "n_gen": r.n_generations,
                         "n_evaluations": r.n_evaluations, "terminated_by_criteria": r.converged,
                         "hypervolume_final": float(r.history["hv"][-1]) if len(r.history.get("hv", [])) else None,
                         "cost_at_pick": float(r.front.cost[r.chosen]),
                         "stack_at_pick_mm": float(r.front.stack_mm[r.chosen])}
                        for r in run["runs"]],
        "hypervolume_reference": list(res.hv_ref),
        "optimizer": {"pop_size": st.pop_size, "n_gen": st.n_gen, "converge": st.converge,
                      "crossover_prob": st.crossover_prob, "mutation_prob_per_var": st.mutation_prob,
                      "eta_crossover": st.eta_crossover, "eta_mutation": st.eta_mutation,
                      "seed": st.seed},
        "geometry": chain.geometry,
    }
    if st.formula == "screw":
        out["cost_model"] = {"model": st.cost_model, "A": st.cost_A, "B": st.cost_B, "k": st.cost_k,
                             "b_um": st.cost_b_um, "angular_length_mm": st.angular_length_mm,
                             "tolerance_unit": "um (rotations: urad x angular_length_mm)"}
        out.update(_screw_summary(run))
        if run["spindle"] is not None:
            out["spindle"] = run["spindle"]
        if sc.reference_accuracy_mm:
            out["paper_table1_h_mm"] = dict(sc.reference_accuracy_mm)
    else:
        out["cost_model"] = {"a": st.a, "b_mm": st.b_mm, "equation": "paper eq. 14"}
        out["values"] = {u.name: {f"{c}_{COMPONENT_UNIT[c]}": float(v) for c, v in
                                  zip(COMPONENTS, unit_values(chain, res.front_X[k:k + 1])[0][6 * i:6 * i + 6])}
                         for i, u in enumerate(chain.units)}
        out["units_accuracy_mm"] = {n: float(v) for n, v in zip(chain.names, ev.unit_stack_mm[k])}
        out["f1_mm"] = float(ev.f1_mm[k])
        out["m_E"] = float(ev.m_E[k])
        out["cost_rel"] = float(ev.cost[k])
        out.update(_paper_summary(run))
    return out


def _pareto_columns(chain, res) -> dict:
    ev = res.front
    cols = {"cost_rel": ev.cost, "chosen": (np.arange(len(res.front_X)) == res.chosen).astype(float)}
    if ev.formula == "screw":
        cols.update(worst_case_mm=ev.worst_case_mm, rss_mm=ev.rss_mm, stack_mm=ev.stack_mm)
        for i, n in enumerate(chain.names):
            cols[f"{n}_worst_case_mm"] = ev.unit_stack_mm[:, i]
    else:
        cols.update(f1_mm=ev.f1_mm, m_E=ev.m_E)
        for i, n in enumerate(chain.names):
            cols[f"{n}_h_mm"] = ev.unit_stack_mm[:, i]
    for j, name in enumerate(chain.variable_names()):
        cols[name] = res.front_X[:, j]
    return cols


# --------------------------------------------------------------------------- pictures
def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _plot_pareto(path, run, alloc) -> None:
    plt = _plt()
    res, st = run["result"], run["result"].settings
    fig, ax = plt.subplots(figsize=(7.2, 4.6))
    if st.formula == "screw":
        for j, r in enumerate(run["runs"]):
            ev = r.front
            ax.plot(ev.stack_mm * 1e3, ev.cost, "o", ms=3.5, color=OKABE[j % 7], alpha=0.8,
                    label=f"front, seed {r.settings.seed} ({r.n_generations} gen)")
        ev, k = res.front, res.chosen
        ax.plot(ev.stack_mm[k] * 1e3, ev.cost[k], "*", ms=16, color="k",
                label=f"knee (picked): {ev.stack_mm[k] * 1e3:.2f} µm, cost {ev.cost[k]:.1f}")
        ax.axvline(st.delta_E_mm * 1e3, color=OKABE[5], ls="--", lw=1.2)
        ax.text(st.delta_E_mm * 1e3, ax.get_ylim()[1], " ΔE", color=OKABE[5], va="top", ha="left")
        what = {"worst_case": "worst-case stack-up m_E", "rss": "RSS stack-up m_E",
                "yield": f"{100 * st.target_yield:g} % quantile of m_E ({st.yield_dist}, "
                         f"{st.yield_draws} draws)"}[st.constraint]
        ax.set_xlabel(f"{what} at the functional point [µm]")
        ax.set_ylabel("cost Σ B/t^k [relative units]")
        ax.set_title("Tolerance–cost front (feasible side of ΔE)")
    else:
        for j, r in enumerate(run.get("converged_runs", [])):
            ev = r.front
            ax.plot(ev.f1_mm * 1e3, ev.cost, "o", ms=3, color=OKABE[j % 7], alpha=0.8,
                    label=f"converged 200×{r.n_generations}, seed {r.settings.seed}")
        pooled_f = np.concatenate([r.front.f1_mm for r in run["runs"]])
        pooled_c = np.concatenate([r.front.cost for r in run["runs"]])
        ax.plot(pooled_f * 1e3, pooled_c, "x", ms=4, color="0.45",
                label=f"16×30 fronts, {len(run['runs'])} seeds")
        t1 = alloc.get("table1")
        if t1:
            ax.plot(t1["f1_lowest_possible_mm"] * 1e3, t1["cost_rel"], "D", ms=9, color=OKABE[5],
                    label="Table 1 (cost; f1 at its lowest possible)")
        ax.set_xlabel("f1 = Σ ω·v / |Σ ω| [µm]")
        ax.set_ylabel("cost Σ 1.2·exp(−h/1.6) [relative units]")
        ax.set_title("Paper's printed model: fronts and Table 1")
    ax.legend(fontsize=7.5, loc="best", framealpha=0.9)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def _plot_convergence(path, run) -> None:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    rs = run.get("converged_runs") or run["runs"]
    for j, r in enumerate(rs):
        h = r.history
        ax.plot(h["n_gen"], h["hv"], color=OKABE[j % 7],
                label=f"seed {r.settings.seed}: {r.n_generations} gen"
                      + (" (stopped by pymoo's criteria)" if r.converged else " (n_gen reached)"))
    ax.set_xlabel("generation [-]")
    ax.set_ylabel("hypervolume of the feasible front [-]\n(objectives / reference point)")
    ax.set_title("Convergence of NSGA-II")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def _plot_stackup(path, run, alloc) -> None:
    plt = _plt()
    st = run["result"].settings
    names = list(alloc["units_worst_case_um"])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10.5, 4.0), gridspec_kw={"width_ratios": [1.1, 1]})
    x = np.arange(len(names))
    a1.bar(x, [alloc["units_worst_case_um"][n] for n in names], color=OKABE[0], width=0.6)
    a1.set_xticks(x, names)
    a1.set_ylabel("unit's own worst case at the functional point [µm]")
    a1.set_title("Contribution of each unit (one part of the budget)")
    a1.grid(axis="y", alpha=0.3)
    labels = ["Σ unit worst cases\n(arithmetic)", "worst case\n(all signs, exact)",
              "RSS", "MC 99 % uniform", "MC 99 % normal"]
    vals = [alloc["sum_of_unit_worst_cases_um"], alloc["worst_case_um"], alloc["rss_um"],
            alloc["monte_carlo"]["uniform"]["p99_um"], alloc["monte_carlo"]["normal"]["p99_um"]]
    y = np.arange(len(labels))
    left = 0.0                           # first row: the units' worst cases stacked end to end
    cmap = plt.get_cmap("cividis")
    for j, n in enumerate(names):
        v = alloc["units_worst_case_um"][n]
        a2.barh(0, v, left=left, height=0.6, color=cmap(0.15 + 0.7 * j / max(1, len(names) - 1)),
                edgecolor="white", label=n)
        left += v
    a2.barh(y[1:], vals[1:], color=[OKABE[0], OKABE[2], OKABE[1], OKABE[3]], height=0.6)
    a2.legend(fontsize=7, loc="lower right", title="units (row 1)", title_fontsize=7)
    for yy, v in zip(y, vals):
        a2.text(v, yy, f" {v:.2f}", va="center", fontsize=8)
    a2.axvline(st.delta_E_mm * 1e3, color=OKABE[5], ls="--", lw=1.2)
    a2.text(st.delta_E_mm * 1e3, 0.5, f" ΔE = {st.delta_E_mm * 1e3:g} µm",
            color=OKABE[5], fontsize=8, va="center")
    a2.set_yticks(y, labels, fontsize=8)
    a2.invert_yaxis()
    a2.set_xlabel("stack-up of the whole chain [µm]")
    a2.set_xlim(0, max(vals + [st.delta_E_mm * 1e3]) * 1.45)
    a2.set_title("Whole chain against ΔE")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def _plot_sensitivity(path, alloc) -> None:
    plt = _plt()
    rk = alloc["sensitivity_ranking"]
    lab = [r["component"] for r in rk]
    share = [100 * r["rss_variance_share"] for r in rk]
    gain = [next(v for kk, v in r.items() if kk.startswith("gain")) for r in rk]
    fig, ax = plt.subplots(figsize=(7.2, 6.4))
    y = np.arange(len(lab))
    ax.barh(y, share, color=OKABE[0], height=0.7)
    for yy, s, g, r in zip(y, share, gain, rk):
        unit = "µm/µrad" if "urad" in "".join(r) else "µm/µm"
        ax.text(s, yy, f" {s:.1f} %  (gain {g:.3g} {unit})", va="center", fontsize=7)
    ax.set_yticks(y, lab, fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("share of the RSS variance at the picked tolerances [%]")
    ax.set_xlim(0, max(share) * 1.6 + 1)
    ax.set_title("Sensitivity ranking of the error components")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def _plot_thermal(path, run, alloc) -> None:
    plt = _plt()
    st = run["result"].settings
    ts = alloc["thermal_series"]
    h = np.asarray(ts["times_s"]) / 3600.0
    fig, ax = plt.subplots(figsize=(7.6, 4.3))
    sp = run["spindle"]
    lab = ("compensation residual (FEM + noise − " + sp.get("compensation_model", "") + ")"
           if sp["compensated"] else f"spindle growth ({sp['model']})")
    ax.plot(h, np.asarray(ts["growth_mm"]) * 1e3, color=OKABE[1], lw=1, label=lab)
    ax.plot(h, np.asarray(ts["worst_case_mm"]) * 1e3, color=OKABE[0], lw=1.4,
            label="worst-case stack: kinematic tolerances + thermal term")
    ax.axhline(st.delta_E_mm * 1e3, color=OKABE[5], ls="--", lw=1.2)
    ax.text(h[-1], st.delta_E_mm * 1e3, f"ΔE = {st.delta_E_mm * 1e3:g} µm ", color=OKABE[5],
            ha="right", va="bottom", fontsize=8)
    ax.set_ylim(top=max(st.delta_E_mm * 1e3, float(np.max(ts["worst_case_mm"])) * 1e3) * 1.12)
    ax.set_xlabel("time in the duty cycle [h]")
    ax.set_ylabel("displacement at the tool [µm]")
    ax.set_title("Thermal budget at every instant of the cycle")
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=2, frameon=False)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


# --------------------------------------------------------------------------- report
def verdict(a: dict) -> list[str]:
    """The report's opening, from ``allocation.json`` alone: does the picked design hold
    the accuracy target, at what cost, and which tolerance to watch (then the key figure);
    the chain, the convergence and every table follow."""
    dE = a["delta_E_mm"] * 1e3
    if a["formula"] == "paper_literal":
        text = (f"With the paper's printed model (eqs. 5-16), the picked tolerances give "
                f"m_E = {a['m_E']:.4g} (target ΔE = {a['delta_E_mm']:g} mm, "
                f"{'met' if a['feasible'] else 'not met'}) at cost {a['cost_rel']:.4g}. "
                "Read it beside the screw-theory allocation, which checks the actual worst "
                "case over every sign and pose.")
        return ["## Verdict", "", text, "", "![the Pareto front and the pick](pareto.png)",
                "", "## Details", ""]
    top = (a.get("sensitivity_ranking") or [{}])[0]
    held = a["worst_case_um"] <= dE * (1 + 1e-9)
    text = (f"The picked tolerances {'hold' if held else 'do not hold'} the target: the worst "
            f"case over every sign and pose is {a['worst_case_um']:.3f} µm against ΔE = "
            f"{dE:g} µm, at relative cost {a['cost_rel']:.4g}; Monte Carlo yield "
            f"{100 * a['yield_normal_3sigma']:.2f} % (normal, t = 3σ).")
    if top:
        text += (f" The tolerance to watch is `{top['component']}`: "
                 f"{100 * top['rss_variance_share']:.0f} % of the RSS variance, "
                 f"{top['worst_case_contribution_um']:.3f} µm of the worst case.")
    if "thermal_worst_case_max_um" in a:
        text += (f" With the spindle's thermal term the stack reaches "
                 f"{a['thermal_worst_case_max_um']:.3f} µm and exceeds ΔE during "
                 f"{100 * a['thermal_fraction_of_cycle_over_delta_E']:.1f} % of the duty cycle.")
    return ["## Verdict", "", text, "", "![the stack-up of the picked design](stackup.png)",
            "", "## Details", ""]


def _chain_lines(sc, chain) -> list[str]:
    """The report's chain table: each unit, its free components and bounds, the poses."""
    L: list[str] = []
    L += ["## Chain", "", "| unit | branch | motion | axis | free components | bounds [mm] / [mrad] |",
          "|---|---|---|---|---|---|"]
    for u, us in zip(chain.units, sc.units):
        tb = next((u.bounds[c] for c in COMPONENTS if c in u.bounds and c not in ROTATIONS), None)
        rb = next((u.bounds[c] for c in ROTATIONS if c in u.bounds), None)
        L.append(f"| {u.name} | {u.branch} | {u.motion} | {us.axis} | {' '.join(u.free)} | "
                 f"{'%g–%g' % tb if tb else '—'} / {'%g–%g' % rb if rb else '—'} |")
    L += ["", f"Poses checked: {', '.join(chain.pose_labels)}.", ""]
    return L


def _convergence_lines(a: dict, formula: str) -> list[str]:
    """The report's convergence table: one row per seed run."""
    L: list[str] = []
    L += ["## Convergence", "", "| seed | generations | evaluations | stopped by pymoo's criteria | "
          "final hypervolume | cost at pick | stack at pick [µm] |", "|---|---|---|---|---|---|---|"]
    if formula == "paper_literal":
        L[-2] = L[-2].replace("stack at pick [µm]", "m_E = |Σω| at pick [-]")
    for c in a["convergence"]:
        s_ = (f"{c['stack_at_pick_mm']:.5f}" if formula == "paper_literal"
              else f"{c['stack_at_pick_mm'] * 1e3:.3f}")
        L.append(f"| {c['seed']} | {c['n_gen']} | {c['n_evaluations']} | {c['terminated_by_criteria']} | "
                 f"{c['hypervolume_final']:.5f} | {c['cost_at_pick']:.5g} | {s_} |")
    L.append("")
    return L


def _screw_lines(run, a: dict) -> list[str]:
    """The screw formula's part of the report: the pick, its tolerances, the
    sensitivity ranking and the thermal term of a spindle unit."""
    st = run["result"].settings
    L: list[str] = []
    L += ["## Picked design (knee of the front)" if st.pick == "knee" else "## Picked design", "",
          f"* feasible: {a['feasible']}; cost {a['cost_rel']:.4g} ({st.cost_model}, A = {st.cost_A:g}, "
          f"B = {st.cost_B:g}, k = {st.cost_k:g}, t in µm, rotations as t·{st.angular_length_mm:g} mm)",
          f"* worst case over every sign and pose: **{a['worst_case_um']:.3f} µm** (ΔE = "
          f"{st.delta_E_mm * 1e3:g} µm); kinematic part alone {a['kinematic_worst_case_um']:.3f} µm",
          f"* RSS: {a['rss_um']:.3f} µm; sum of the units' own worst cases {a['sum_of_unit_worst_cases_um']:.3f} µm",
          f"* Monte Carlo yield (m_E <= ΔE at every pose, {N_DRAWS:,} draws): uniform "
          f"{100 * a['yield_uniform']:.2f} %, normal with t = 3σ {100 * a['yield_normal_3sigma']:.3f} %",
          "", "Tolerances (± band of each error component):", "",
          "| unit | " + " | ".join(f"{c} [{'µrad' if c in ROTATIONS else 'µm'}]" for c in COMPONENTS)
          + " | unit's worst case at the point [µm] |", "|---|" + "---|" * 7]
    for n, tt in a["tolerances"].items():
        L.append(f"| {n} | " + " | ".join(f"{v:.3f}" for v in tt.values())
                 + f" | {a['units_worst_case_um'][n]:.3f} |")
    L += ["", "## Sensitivity ranking (share of the RSS variance at the picked tolerances)", "",
          "| rank | component | gain | tolerance | worst-case contribution [µm] | RSS share |",
          "|---|---|---|---|---|---|"]
    for i, r in enumerate(a["sensitivity_ranking"], 1):
        g = next((kk, v) for kk, v in r.items() if kk.startswith("gain"))
        t = next((kk, v) for kk, v in r.items() if kk.startswith("tolerance"))
        L.append(f"| {i} | {r['component']} | {g[1]:.4g} {'µm/µrad' if 'urad' in g[0] else 'µm/µm'} | "
                 f"{t[1]:.3f} {'µrad' if 'urad' in t[0] else 'µm'} | "
                 f"{r['worst_case_contribution_um']:.3f} | {100 * r['rss_variance_share']:.2f} % |")
    sp = run["spindle"]
    if sp is not None:
        ts = a["thermal_series"]
        wc = np.asarray(ts["worst_case_mm"]) * 1e3
        over = float(np.mean(wc > st.delta_E_mm * 1e3))
        L += ["", "## Thermal term (spindle axis, every instant of the duty cycle)", "",
              f"* spindle unit `{sp['unit']}`, q = {sp['q_W_m2']:g} W/m², paper 24 h cycle, Δτ = {sp['dtau_s']:g} s",
              f"* {'compensated: residual = FEM growth + measurement noise (σ = ' + format(sp['noise_um'], 'g') + ' µm) − ' + sp['compensation_model'] + ' prediction' if sp['compensated'] else 'uncompensated growth, model ' + sp['model']}",
              f"* largest |thermal term| {sp['peak_um']:.3f} µm at t = {sp['t_peak_s'] / 3600:.2f} h"
              + (f"; FEM peak {sp['peak_fem_um']:.3f} µm, prediction peak {sp['peak_prediction_um']:.3f} µm, "
                 f"noise-free residual {sp['true_residual_um']:.3f} µm" if sp["compensated"] else ""),
              f"* worst-case stack with it: max over the cycle {wc.max():.3f} µm; over ΔE during "
              f"{100 * over:.1f} % of the cycle", ""]
    return L


def _paper_lines(run, a: dict) -> list[str]:
    """The paper_literal part of the report: Table 1 in the seed spread, Table 1's
    cost, and the converged runs (the paper's own optimum)."""
    st = run["result"].settings
    L: list[str] = []
    sp_ = a["seed_spread"]
    L += ["## The printed model (eqs. 5-16), as the paper ran it", "",
          f"NSGA-II {st.pop_size} × {st.n_gen}, {a['n_seeds']} seeds. Where the paper's Table 1 falls "
          "in the spread of picked members (compromise pick) and of all final-front members:", "",
          "| unit | Table 1 [mm] | picked: min / median / max [mm] | percentile in picked | "
          "percentile in fronts |", "|---|---|---|---|---|"]
    for n, d in sp_.items():
        L.append(f"| {n} | {d.get('table1_mm', float('nan')):.5f} | {d['picked_min_mm']:.5f} / "
                 f"{d['picked_median_mm']:.5f} / {d['picked_max_mm']:.5f} | "
                 f"{d.get('table1_percentile_of_picked', float('nan')):.0f} | "
                 f"{d.get('table1_percentile_of_fronts', float('nan')):.0f} |")
    if "table1" in a:
        L += ["", f"Table 1's cost (eq. 14): {a['table1']['cost_rel']:.5f}; its f1 is at least "
                  f"{a['table1']['f1_lowest_possible_mm']:.5f} mm (f1 is an |ω|-weighted mean of "
                  "the h_j when the ω_j are aligned, larger otherwise)."]
        if "converged_front_cost_at_or_below_its_f1" in a["table1"]:
            L += ["", f"The converged front reaches cost {a['table1']['converged_front_cost_at_or_below_its_f1']:.5f} "
                      f"at f1 <= {a['table1']['f1_lowest_possible_mm']:.5f} mm: Table 1 is "
                      + ("**dominated** (higher cost at no better f1)." if a["table1"]["dominated_by_converged_front"]
                         else "not dominated.")]
    L += ["", "## The paper's own optimum (converged)", "",
          "| seed | generations | stopped by criteria | front | lowest cost | f1 there [mm] | "
          "h_j there [mm] |", "|---|---|---|---|---|---|---|"]
    for c in a["converged"]:
        L.append(f"| {c['seed']} | {c['n_gen']} | {c['terminated_by_criteria']} | {c['front_size']} | "
                 f"{c['cost_min']:.5f} | {c['f1_at_cost_min_mm']:.5f} | "
                 + ", ".join(f"{k} {v:.5f}" for k, v in c["h_at_cost_min_mm"].items()) + " |")
    return L


def _report(run, a: dict, command: str) -> str:
    """``report.md``: conventions, chain, result, the numbers behind every picture."""
    sc, chain, res = run["scenario"], run["chain"], run["result"]
    st = res.settings
    L = [f"# Precision allocation: {sc.name}", ""] + verdict(a) + \
        [sc.description, "", f"Generated by `{command}`.", ""]
    L += _chain_lines(sc, chain) + _convergence_lines(a, st.formula)
    L += _screw_lines(run, a) if st.formula == "screw" else _paper_lines(run, a)
    L += ["", "See `allocation.json` for every number, `pareto.csv` for the whole front."]
    return "\n".join(L) + "\n"

def write_allocation(run: dict, out_dir: Path, command: str) -> dict:
    """Write every file of :data:`WRITES` that the run has into ``out_dir`` (a staging
    folder) and return the ``allocation.json`` document as written."""
    alloc = _allocation_json(run)
    st = run["result"].settings
    stage = Path(out_dir)
    write_csv(stage / "pareto.csv", _pareto_columns(run["chain"], run["result"]))
    _plot_pareto(stage / "pareto.png", run, alloc)
    _plot_convergence(stage / "convergence.png", run)
    if st.formula == "screw":
        _plot_stackup(stage / "stackup.png", run, alloc)
        _plot_sensitivity(stage / "sensitivity.png", alloc)
        if run["spindle"] is not None:
            _plot_thermal(stage / "thermal.png", run, alloc)
    (stage / "report.md").write_text(_report(run, alloc, command), encoding="utf-8")
    if "thermal_series" in alloc:   # the series lives in its own CSV, not the JSON
        ts = alloc.pop("thermal_series")
        write_csv(stage / "thermal.csv", {"time_s": ts["times_s"], "thermal_term_mm": ts["growth_mm"],
                                          "worst_case_mm": ts["worst_case_mm"]})
        alloc["thermal_worst_case_max_um"] = float(np.max(ts["worst_case_mm"]) * 1e3)
        alloc["thermal_fraction_of_cycle_over_delta_E"] = float(
            np.mean(np.asarray(ts["worst_case_mm"]) > st.delta_E_mm))
    write_json(stage / "allocation.json", alloc)
    write_html_report(stage)
    return alloc


def allocation_terminal_line(run: dict, alloc: dict, out) -> str:
    """The one line ``arfem allocate`` prints: the pick's key figures and where it went
    (named for its command: ``arfem compensate`` and ``arfem diagnose`` have their own)."""
    r = run["result"]
    st = r.settings
    if st.formula == "screw":
        return (f"allocate: {run['scenario'].name}: {'feasible' if r.feasible else 'INFEASIBLE'}, "
                f"worst case {alloc['worst_case_um']:.3f} µm (ΔE {st.delta_E_mm * 1e3:g} µm), "
                f"RSS {alloc['rss_um']:.3f} µm, yield {100 * alloc['yield_uniform']:.2f} % uniform / "
                f"{100 * alloc['yield_normal_3sigma']:.2f} % normal, cost {alloc['cost_rel']:.4g}, "
                f"{r.n_generations} gen{' (converged)' if r.converged else ''} -> {out}")
    return (f"allocate: {run['scenario'].name} (paper_literal): f1 {alloc['f1_mm']:.5f} mm, "
            f"cost {alloc['cost_rel']:.5f}; "
            + ", ".join(f"{n} {v:.5f} mm" for n, v in alloc["units_accuracy_mm"].items()) + f" -> {out}")
