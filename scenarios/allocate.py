"""``arfem allocate SCENARIO --out DIR [--force]``: precision allocation over a motion chain.

Reads an allocation scenario (:mod:`arfem.models.allocation.scenario`), solves the
NSGA-II allocation of Zhou et al. (2020) and writes, atomically:

* ``pareto.csv``      -- the Pareto front (one row per member, unit-suffixed columns)
* ``allocation.json`` -- the picked member: ``units_accuracy_mm`` {unit: accuracy [mm]},
  ``m_E_mm``, ``h_E_mm_per_rad``, ``cost_rel`` and more, every quantity's unit in its name
* ``pareto.png``      -- the front (scenario formula and the other one), unit accuracies
* ``report.md``       -- conventions, geometry, result, screw-vs-paper comparison, seeds
"""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from arfem.models.allocation.problem import (COMPONENT_UNIT, COMPONENTS, TWIST_INDEX, allocate,
                                       evaluate, unit_twists)
from arfem.io import read_toml, write_csv, write_json
from arfem.models.allocation.scenario import AllocationScenario, build_chain, parse_scenario
from arfem.scenarios.outdir import prepare_out_dir, staged_out_dir

__all__ = ["add_parser", "main", "run_allocation", "load_allocation_scenario"]

def load_allocation_scenario(path) -> AllocationScenario:
    """Read and validate an allocation scenario file; :class:`InputError` names the file and key."""
    p = Path(path)
    return parse_scenario(read_toml(p), str(p))


#: seeds of the seed-sensitivity table in the report
SEEDS = (1, 2, 3, 4, 5)


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "allocate", help="precision allocation over a chain of meta-action units (NSGA-II)",
        description="Allocate accuracy to the meta-action units of a motion chain "
                    "(Zhou et al. 2020): min(|pitch|, cost) s.t. m_E <= delta_E.")
    p.add_argument("scenario", help="allocation scenario TOML (e.g. scenarios/pallet_changer.toml)")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--force", action="store_true", help="replace files in a non-empty --out")
    p.set_defaults(func=main)


def _row(chain, ev, k) -> dict:
    return {"m_E_mm": float(ev.m_E_mm[k]), "h_E_mm_per_rad": float(ev.h_E_mm_per_rad[k]),
            "cost_rel": float(ev.cost[k]), "m_E_worst_case_mm": float(ev.m_E_worst_case_mm[k]),
            "units_accuracy_mm": {n: float(a) for n, a in zip(chain.names, ev.unit_accuracy_mm[k])}}


def run_allocation(scenario_path) -> dict:
    """Everything the writers need: scenario, chain, main result and comparisons."""
    sc = load_allocation_scenario(scenario_path)
    chain, spindle = build_chain(sc)
    st = sc.settings
    main_res = allocate(chain, st)
    other = "paper" if st.formula == "screw" else "screw"
    other_res = allocate(chain, replace(st, formula=other))
    seeds = []
    for f in ("screw", "paper"):
        for s in SEEDS:
            r = main_res if (f == st.formula and s == st.seed) else allocate(
                chain, replace(st, formula=f, seed=s))
            k = r.chosen
            seeds.append({"formula": f, "seed": s, "feasible": r.feasible,
                          "n_front": len(r.front_X), **_row(chain, r.front, k)})
    return {"scenario": sc, "chain": chain, "spindle": spindle, "result": main_res,
            "other": other_res, "other_formula": other, "seeds": seeds}


def _allocation_json(run) -> dict:
    sc, chain, res = run["scenario"], run["chain"], run["result"]
    ev, k, st = res.front, res.chosen, res.settings
    X = res.front_X[k:k + 1]
    xis = unit_twists(chain, X)[0]
    errors = {}
    for i, u in enumerate(chain.units):
        e = {}
        for c in COMPONENTS:
            v = xis[i, TWIST_INDEX[c]] * (1e3 if COMPONENT_UNIT[c] == "mrad" else 1.0)
            e[f"{c}_{COMPONENT_UNIT[c]}"] = float(v)
        e["free"] = list(u.free)
        errors[u.name] = e
    ev_other = evaluate(chain, X, st, formula=run["other_formula"])
    ko = run["other"].chosen
    ev_other_in_main = evaluate(chain, run["other"].front_X[ko:ko + 1], st, formula=st.formula)
    out = {
        "scenario": sc.name,
        "source": str(sc.source),
        "formula": st.formula,
        "constraint": st.constraint,
        "feasible": bool(res.feasible),
        "units_accuracy_mm": {n: float(a) for n, a in zip(chain.names, ev.unit_accuracy_mm[k])},
        "m_E_mm": float(ev.m_E_mm[k]),
        "h_E_mm_per_rad": float(ev.h_E_mm_per_rad[k]),
        "cost_rel": float(ev.cost[k]),
        "m_E_worst_case_mm": float(ev.m_E_worst_case_mm[k]),
        "screw_magnitude_rad": float(ev.screw_magnitude[k]),
        "axial_translation_mm": float(ev.axial_translation_mm[k]),
        "xi_E_rad_mm": [float(v) for v in ev.xi_E[k]],
        "delta_E_mm": st.delta_E_mm,
        "working_radius_mm": st.working_radius_mm,
        "errors": errors,
        "front_size": int(len(res.front_X)),
        "pick": st.pick,
        "n_evaluations": res.n_evaluations,
        "optimizer": {"pop_size": st.pop_size, "n_gen": st.n_gen, "crossover_prob": st.crossover_prob,
                      "mutation_prob_per_var": st.mutation_prob, "eta_crossover": st.eta_crossover,
                      "eta_mutation": st.eta_mutation, "seed": st.seed},
        "cost_model": {"a": st.a, "b_mm": st.b_mm},
        "same_allocation_other_formula": {
            "formula": run["other_formula"], "m_E_mm": float(ev_other.m_E_mm[0]),
            "h_E_mm_per_rad": float(ev_other.h_E_mm_per_rad[0])},
        "other_formula_allocation": {
            "formula": run["other_formula"], "feasible": bool(run["other"].feasible),
            **_row(chain, run["other"].front, ko),
            f"m_E_mm_under_{st.formula}": float(ev_other_in_main.m_E_mm[0])},
        "seeds": run["seeds"],
    }
    if sc.reference_accuracy_mm:
        out["reference_accuracy_mm"] = dict(sc.reference_accuracy_mm)
    if run["spindle"] is not None:
        out["spindle"] = run["spindle"]
        costed = [u.name for u in chain.units if u.costed]
        out["budget_left_mm"] = float(st.delta_E_mm - run["spindle"]["dz_mm"])
        out["kinematic_units"] = costed
    return out


def _pareto_columns(chain, res) -> dict:
    ev = res.front
    cols = {"h_E_mm_per_rad": ev.h_E_mm_per_rad, "abs_h_E_mm_per_rad": np.abs(ev.h_E_mm_per_rad),
            "cost_rel": ev.cost, "m_E_mm": ev.m_E_mm, "m_E_worst_case_mm": ev.m_E_worst_case_mm,
            "chosen": (np.arange(len(res.front_X)) == res.chosen).astype(float)}
    for i, n in enumerate(chain.names):
        cols[f"{n}_accuracy_mm"] = ev.unit_accuracy_mm[:, i]
    for j, name in enumerate(chain.variable_names()):
        cols[name] = res.front_X[:, j]
    return cols


def _plot(path, run) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    chain, res, oth = run["chain"], run["result"], run["other"]
    st = res.settings
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.2))
    for r, lab, mk, col in ((res, st.formula, "o", "C0"), (oth, run["other_formula"], "s", "C1")):
        ev = r.front
        h = np.abs(ev.h_E_mm_per_rad)
        ax.scatter(h, ev.cost, marker=mk, facecolors=col if r is res else "none", edgecolors=col,
                   label=f"{lab} form{'' if r.feasible else ' (INFEASIBLE)'}")
        ax.scatter(h[r.chosen], ev.cost[r.chosen], marker="*", s=180, color="k", zorder=5)
    ax.set_xscale("symlog", linthresh=1.0)
    ax.set_xlabel("|h_E| pitch of the chain error screw [mm/rad]")
    ax.set_ylabel("cost Σ a·exp(−x/b) [-]")
    ax.set_title(f"Pareto front, NSGA-II pop {st.pop_size}, {st.n_gen} gen, seed {st.seed}")
    ax.legend(fontsize=8)
    names = chain.names
    x = np.arange(len(names))
    w = 0.38
    acc = res.front.unit_accuracy_mm[res.chosen] * 1e3
    bx.bar(x - w / 2, acc, w, label=f"this work ({st.formula} form)")
    ref = run["scenario"].reference_accuracy_mm
    if ref:
        bx.bar(x + w / 2, [ref.get(n, np.nan) * 1e3 for n in names], w, label="reference (paper)")
    bx.axhline(st.delta_E_mm * 1e3, color="r", ls="--", lw=1, label="ΔE")
    bx.set_xticks(x, names)
    bx.set_ylabel("unit accuracy at the functional point [µm]")
    bx.set_title("picked allocation (★)")
    bx.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _fmt(v, nd=5):
    return "—" if v is None or (isinstance(v, float) and not np.isfinite(v)) else f"{v:.{nd}f}"


def _report(run, alloc: dict, command: str) -> str:
    sc, chain, res = run["scenario"], run["chain"], run["result"]
    st = res.settings
    L = [f"# Precision allocation: {sc.name}", "", sc.description, "",
         f"Generated by `{command}`.", "",
         "## Conventions", "",
         "* Error screw of a unit pair ξ = [Δα, Δβ, Δγ; Δx, Δy, Δz] (rad; mm), applied in the "
         "unit's frame after its nominal pose (scenario files give angles in mrad = mm/m).",
         "* Chain error at the functional point: "
         + ("ξ_E = Σ_i Ad(H_i⁻¹) ξ_i, H_i = pose of the functional point in unit i's frame "
            "(exact in the geometry, first order in the errors)." if st.formula == "screw" else
            "the paper's form: product of the raw pair error matrices without the nominal poses."),
         "* Pitch h_E = ω·v/|ω|² [mm/rad]; the objective is |h_E|.",
         f"* m_E = |v_E| + r·|ω_E| [mm], r = working radius = {st.working_radius_mm:g} mm: the "
         "largest displacement of a point within r of the functional point; the constraint is "
         f"m_E ≤ ΔE = {st.delta_E_mm:g} mm ({st.constraint}). The screw-theory magnitude "
         "(|ω_E| in rad, |v_E| if ω_E = 0) is reported too but cannot be compared with a length.",
         "* Unit accuracy x_i [mm] = |v_i| + r·|ω_i| of unit i's own screw mapped to the "
         "functional point; cost = Σ a·exp(−x_i/b), "
         f"a = {st.a:g}, b = {st.b_mm:g} mm (paper eq. 14), over the designed units.",
         f"* m_E worst case = Σ_j |ξ_j|·(|column j of Ad|) -- the bound over unknown error "
         "signs, i.e. what a tolerance (rather than a known error) guarantees.",
         "", "## Chain", "",
         "| unit | motion | origin in base frame [mm] | free components | translation bounds [mm] "
         "| rotation bounds [mrad] |",
         "|---|---|---|---|---|---|"]
    g = np.eye(4)
    for u in chain.units:
        g = g @ u.pose
        tb = next((u.bounds[c] for c in ("dx", "dy", "dz") if c in u.bounds), None)
        rb = next((u.bounds[c] for c in ("dalpha", "dbeta", "dgamma") if c in u.bounds), None)
        fx = ", ".join(f"{c} = {v:g} {COMPONENT_UNIT[c]}" for c, v in u.fixed.items() if v)
        L.append(f"| {u.name} | {u.motion} | {np.round(g[:3, 3], 3).tolist()} | "
                 f"{' '.join(u.free) or 'none (fixed' + (': ' + fx if fx else '') + ')'} | "
                 f"{'%g–%g' % tb if tb else '—'} | {'%g–%g' % rb if rb else '—'} |")
    gt = g @ chain.tool
    L += ["", f"Functional point in the base frame: {np.round(gt[:3, 3], 3).tolist()} mm.", ""]
    sp = run["spindle"]
    if sp is not None:
        L += ["## Spindle thermal growth (fixed budget term)", "",
              f"* model `{sp['model']}`, q = {sp['q_W_m2']:g} W/m², paper duty cycle, "
              f"Δτ = {sp['dtau_s']:g} s, {sp['position']}",
              f"* peak growth of the model: {sp['peak_growth_um']:.3f} µm"]
        if sp["compensated"]:
            L.append(f"* compensated by the model: residual max|model − FEM| = "
                     f"{sp['residual_um']:.3f} µm (FEM peak {sp['peak_growth_fem_um']:.3f} µm)")
        L += [f"* fixed spindle Δz = {sp['dz_mm'] * 1e3:.3f} µm; budget left for the kinematic "
              f"units ΔE − Δz = {alloc['budget_left_mm'] * 1e3:.3f} µm", ""]
    L += ["## Result", "",
          f"NSGA-II, population {st.pop_size}, {st.n_gen} generations, SBX p = {st.crossover_prob:g} "
          f"η = {st.eta_crossover:g}, PM p/var = {st.mutation_prob:g} η = {st.eta_mutation:g}, "
          f"seed {st.seed}: {res.n_evaluations} evaluations, {len(res.front_X)} front member(s), "
          f"picked by `{st.pick}`.", ""]
    if not res.feasible:
        L += ["**No candidate met m_E ≤ ΔE.** The front below is the least-violating candidate.",
              ""]
    ref = sc.reference_accuracy_mm or {}
    L += [f"| quantity | this work ({st.formula}) |" + (" reference |" if ref else ""),
          "|---|---|" + ("---|" if ref else "")]
    for n in chain.names:
        L.append(f"| {n} accuracy [mm] | {alloc['units_accuracy_mm'][n]:.5f} |"
                 + (f" {_fmt(ref.get(n))} |" if ref else ""))
    L += [f"| m_E [mm] | {alloc['m_E_mm']:.5f} |" + (" ≤ ΔE |" if ref else ""),
          f"| m_E worst case [mm] | {alloc['m_E_worst_case_mm']:.5f} |" + (" |" if ref else ""),
          f"| h_E [mm/rad] | {alloc['h_E_mm_per_rad']:.4g} |" + (" |" if ref else ""),
          f"| cost [-] | {alloc['cost_rel']:.6f} |" + (" |" if ref else ""), "",
          "Errors of the picked allocation (translations mm, rotations mrad):", "",
          "| unit | " + " | ".join(f"{c} [{COMPONENT_UNIT[c]}]" for c in COMPONENTS) + " |",
          "|---|" + "---|" * len(COMPONENTS)]
    for n, e in alloc["errors"].items():
        L.append(f"| {n} | " + " | ".join(f"{e[f'{c}_{COMPONENT_UNIT[c]}']:.5f}"
                                         for c in COMPONENTS) + " |")
    so, oa = alloc["same_allocation_other_formula"], alloc["other_formula_allocation"]
    L += ["", "## Screw theory vs the paper's printed form", "",
          f"* The picked allocation evaluated with the `{so['formula']}` form: m_E = "
          f"{so['m_E_mm']:.5f} mm, h_E = {so['h_E_mm_per_rad']:.4g} mm/rad "
          f"(`{st.formula}`: m_E = {alloc['m_E_mm']:.5f} mm, h_E = {alloc['h_E_mm_per_rad']:.4g}).",
          f"* Optimising with the `{oa['formula']}` form instead (same seed) picks: "
          + ", ".join(f"{n} {v:.5f}" for n, v in oa["units_accuracy_mm"].items())
          + f" mm; m_E = {oa['m_E_mm']:.5f} mm under its own form but "
          f"{oa[f'm_E_mm_under_{st.formula}']:.5f} mm under the `{st.formula}` form "
          f"(ΔE = {st.delta_E_mm:g} mm).", "",
          "## Seed sensitivity (same settings, picked member)", "",
          "| form | seed | feasible | front | m_E [mm] | m_E worst [mm] | h_E [mm/rad] | cost | "
          + " | ".join(f"{n} [mm]" for n in chain.names) + " |",
          "|---|---|---|---|---|---|---|---|" + "---|" * len(chain.names)]
    for s in run["seeds"]:
        L.append(f"| {s['formula']} | {s['seed']} | {s['feasible']} | {s['n_front']} | "
                 f"{s['m_E_mm']:.5f} | {s['m_E_worst_case_mm']:.5f} | {s['h_E_mm_per_rad']:.4g} | "
                 f"{s['cost_rel']:.6f} | " + " | ".join(f"{v:.5f}" for v in s["units_accuracy_mm"].values())
                 + " |")
    L += ["", "## Pareto front", "", "See `pareto.csv` (all members, all variables) and "
          "`pareto.png`.", "", "| # | |h_E| [mm/rad] | cost | m_E [mm] | "
          + " | ".join(f"{n} [mm]" for n in chain.names) + " |",
          "|---|---|---|---|" + "---|" * len(chain.names)]
    ev = res.front
    for k in range(len(res.front_X)):
        L.append(f"| {k}{' ★' if k == res.chosen else ''} | {abs(ev.h_E_mm_per_rad[k]):.4g} | "
                 f"{ev.cost[k]:.6f} | {ev.m_E_mm[k]:.5f} | "
                 + " | ".join(f"{v:.5f}" for v in ev.unit_accuracy_mm[k]) + " |")
    return "\n".join(L) + "\n"


def main(args) -> int:
    out = prepare_out_dir(args.out, args.force)       # refuse early, before computing
    run = run_allocation(args.scenario)
    alloc = _allocation_json(run)
    command = f"arfem allocate {args.scenario} --out {args.out}" + (" --force" if args.force else "")
    with staged_out_dir(out, args.force) as stage:
        write_csv(Path(stage) / "pareto.csv", _pareto_columns(run["chain"], run["result"]))
        write_json(Path(stage) / "allocation.json", alloc)
        _plot(Path(stage) / "pareto.png", run)
        (Path(stage) / "report.md").write_text(_report(run, alloc, command), encoding="utf-8")
    r = run["result"]
    print(f"allocate: {run['scenario'].name}: {'feasible' if r.feasible else 'INFEASIBLE'}, "
          f"m_E = {alloc['m_E_mm']:.5f} mm (ΔE {r.settings.delta_E_mm:g}), "
          f"h_E = {alloc['h_E_mm_per_rad']:.4g} mm/rad, cost = {alloc['cost_rel']:.6f}; "
          + ", ".join(f"{n} {v:.5f} mm" for n, v in alloc["units_accuracy_mm"].items()) + f" -> {out}")
    return 0
