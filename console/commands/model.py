"""`drs model show PATH`: a calibrated model file, for a person to read before flying it."""

from __future__ import annotations

import argparse
import json

from console.commands.argparser import input_file

IN_BANDS = {"model": "the model's terms", "payload": "the payload's drag law"}
OUTSIDE_BANDS = {"model": "the model's terms", "payload": "the plain restart from the nominal payload"}
"""How ``drs model show`` names the live laws (``LiveSettings.law`` in the bands, ``restart`` outside them)."""


def register(subparsers: argparse._SubParsersAction) -> None:
    model = subparsers.add_parser(
        "model", help="calibrated model files written by drs calibrate --save-model"
    )
    actions = model.add_subparsers(dest="model_command", metavar="ACTION", required=True)
    show = actions.add_parser("show", help="print what a model holds and where it came from")
    show.add_argument("path", type=input_file("PATH"), help="the model file; - reads standard input")
    show.add_argument("--json", action="store_true", help="print the file's content, validated")
    show.set_defaults(func=run_show)


def run_show(args: argparse.Namespace) -> int:
    from predictor.prediction import load_model

    model = load_model(args.path)
    if args.json:
        print(json.dumps(model.to_dict(), indent=2, ensure_ascii=False))
        return 0
    p, prov = model.payload, model.provenance
    lines = [
        f"model     {model.label()}",
        f"payload   {p.name}: {p.mass_kg:g} kg, Cd·A {p.cda_m2:g} m²",
    ]
    if model.terms:
        live_only = set(model.live_only())
        reasons = {
            g.get("term"): g.get("reason") for g in prov.get("preflight_gate") or [] if isinstance(g, dict)
        }
        for term in model.terms:
            values = ", ".join(f"{k} {v}" for k, v in term.parameters().items())
            if model.preflight is None:
                flown = "pre-flight and live (written before the pre-flight gate: not judged)"
            elif term.name in live_only:
                why = str(reasons.get(term.name) or "the pre-flight gate left it out").removeprefix(
                    "live-only: "
                )
                flown = f"LIVE-ONLY ({why})"
            elif term.name == "descent_rate_scale" and term not in model.preflight:
                flown = "live (λ under every term; pre-flight flies its own, below)"
            else:
                why = str(reasons.get(term.name) or "").removeprefix("pre-flight: ")
                flown = "pre-flight and live" + (f" ({why})" if why else "")
            lines.append(f"term      {term.name} ({term.family}): {values}; {flown}")
        rate_gate = str(reasons.get("descent_rate_scale") or "")
        for term in model.preflight_law():
            if term not in model.terms:
                values = ", ".join(f"{k} {v}" for k, v in term.parameters().items())
                why = (
                    f"λ = 1, the plain law's rate: {rate_gate.removeprefix('live-only: ')}"
                    if rate_gate.startswith("live-only")
                    else "λ under the pre-flight terms"
                )
                lines.append(f"term      {term.name} ({term.family}): {values}; pre-flight only ({why})")
    else:
        lines.append("term      none: calibration found no effect that helped held-out flights")
    if model.rate_prior is not None:
        r = model.rate_prior
        # Since schema 6 the pre-flight interval is the spread about the pre-flight law's λ, its own line.
        before = "" if model.preflight_spread else f" (pre-flight descent time ±{100 * r.log_sigma:.0f} % 1σ)"
        lines.append(
            f"λ prior   median {r.median:.4g}, sd of ln λ {r.log_sigma:.3g} over {r.flights} flights: each flight's "
            f"own rate factor on the shape{before}"
        )
    if model.preflight_spread is not None:
        spread = model.preflight_spread
        lines.append(
            f"λ spread  pre-flight: σ of ln λ {spread.log_sigma:.3g} about the pre-flight law's λ (its held-out "
            f"descent times over {spread.flights} flights; pre-flight descent time ±{100 * spread.log_sigma:.0f} % 1σ)"
        )
    stability = prov.get("selection_stability")
    if isinstance(stability, dict) and stability:
        lines.append(
            "stability "
            + ", ".join(f"{name} chosen in {share:.0%} of folds" for name, share in stability.items())
        )
    if model.ellipse is not None:
        e = model.ellipse
        lines.append(
            f"ellipse   σ0 {e.sigma0_km:.3g} km, h {e.h:.3g}, k {e.k_km2_per_h2:.3g} km²/h², q {e.q:.3g}"
        )
    else:
        lines.append("ellipse   none (too few flights): predictions use the paper's launch model")
    if model.live is not None:
        sigma = model.live.error_model
        lines.append(
            "live      "
            + ("; ".join(b.describe() for b in model.live.correction.bands) or "plain re-prediction")
        )
        lines.append(
            f"live law  in the bands: {IN_BANDS[model.live.law]}, with the flight's own λ where a band updates it; "
            f"outside them: {OUTSIDE_BANDS[model.live.restart]}"
        )
        gain = model.live.correction.wind_gain
        lines.append(
            "live wind "
            + (
                "all of the measured error carried (no gain learned)"
                if gain is None
                else "share of the measured error carried, by report height: "
                + ", ".join(f"{h:g} km {g:.2f}" for h, g in zip(gain.heights_km, gain.gains, strict=True))
            )
        )
        lines.append(
            "live 1σ   "
            + ", ".join(
                f"{h:g} km {a:.2f}×{c:.2f} km"
                for h, a, c in zip(
                    sigma.heights_km, sigma.sigma_parallel_km, sigma.sigma_perpendicular_km, strict=True
                )
            )
        )
    else:
        lines.append(
            "live      not evaluated with this law: drs live flies its shape with each flight's own λ update and "
            "the default ellipse, and says so (drs live evaluate --save-model)"
        )
    flights = prov.get("flights") or []
    lines.append(f"flights   {len(flights)}: {', '.join(flights[:8])}{' …' if len(flights) > 8 else ''}")
    lines.append(f"weather   {prov.get('weather', 'unknown')}")
    for label, key in (("before", "held_out_before"), ("after", "held_out_after")):
        scores = prov.get(key) or {}
        parts = [f"{metric} mean {value.get('mean'):.3f}" for metric, value in scores.items()
                 if isinstance(value, dict) and isinstance(value.get("mean"), int | float)]  # fmt: skip
        if parts:
            lines.append(f"{label:<9} (held out) {', '.join(parts)}")
    lines.append(f"made by   drs {prov.get('project_version', '?')}: {prov.get('command', '?')}")
    print("\n".join(lines))
    return 0
