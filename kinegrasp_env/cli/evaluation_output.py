"""What ``kinegrasp evaluate`` prints, whichever robot ran: one header, P(FC), Q's moments
and the outcome counts (the hold scores and the coupled jaws' push where asked for)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from kinegrasp_env.wording import fixed

__all__ = ["Evaluation", "evaluation_record", "hold_lines", "print_evaluation"]


@dataclass(frozen=True)
class Evaluation:
    """One evaluation's figures as ``evaluate`` prints them.

    Attributes:
        what: the grasp, e.g. ``cube grasp 0 of robot panda``.
        noise: the noise, e.g. ``sigma = 0.0133 rad (gaussian)`` or ``noise spec FILE``.
        samples: draws.
        friction: the contacts' mu, or None where each draw takes its own.
        contacts: the robot's contact model (``point``, ``soft``, ...).
        p_fc, p_fc_ci: P(FC) and its 95% interval.
        q_nominal, q_mean, q_std, q_skew: Q at the nominal closing and its moments over the
            force-closure draws (dimensionless).
        outcomes: outcome name -> draws.
    """

    what: str
    noise: str
    samples: int
    friction: float | None
    contacts: str
    p_fc: float
    p_fc_ci: tuple[float, float]
    q_nominal: float
    q_mean: float
    q_std: float
    q_skew: float
    outcomes: dict[str, int]


def print_evaluation(run: Evaluation, extra: list[str] | None = None) -> None:
    """Print ``run``; ``extra``: lines printed after Q's (hold scores, the jaws' push)."""
    mu = "friction mu per draw" if run.friction is None else f"friction mu {run.friction:g}"
    lo, hi = run.p_fc_ci
    print(f"{run.what}, {run.noise}, {run.samples} draws, {mu}")
    print(f"  P(FC)   = {run.p_fc:.4f}  (95% CI {lo:.4f} .. {hi:.4f})")
    def shown(value: float, digits: int = 5) -> str:  # a moment of too few draws: "-"
        return "-" if math.isnan(value) else fixed(value, digits)

    closed = run.outcomes.get("force_closure", 0)
    undefined = any(math.isnan(v) for v in (run.q_mean, run.q_std, run.q_skew))
    note = f" ({closed} of them: '-' where too few or all equal)" if undefined else ""
    print(f"  Q (Ferrari-Canny, dimensionless, {run.contacts} contacts; mean, std, skewness "
          f"over the force-closure draws{note}): nominal {run.q_nominal:.5f}, mean "
          f"{shown(run.q_mean)}, std {shown(run.q_std)}, skewness {shown(run.q_skew, 3)}, "
          f"error (nominal - mean) {shown(run.q_nominal - run.q_mean)}")
    for line in extra or []:
        print(line)
    print("  outcomes: " + ", ".join(f"{k} {v}" for k, v in run.outcomes.items()))


def hold_lines(record: dict) -> list[str]:
    """The lines ``evaluate`` prints for the hold scores in ``record`` (its ``--json`` keys:
    ``p_hold``, ``p_hold_ci``, ``hold_margin``, ``hold_simulator``; ``p_hold_static``,
    ``p_hold_static_ci``, ``mass_kg``)."""
    lines = []
    if "p_hold" in record:
        lo, hi = record["p_hold_ci"]
        lines.append(f"  P(hold) = {record['p_hold']:.4f}  (95% CI {lo:.4f} .. {hi:.4f}; the "
                     f"quick holding test in {record['hold_simulator']} on the same draws; "
                     f"mean margin {record['hold_margin']:.3f}: how far the draws got "
                     "through it, 0 to 1)")
    if "p_hold_static" in record:
        lo, hi = record["p_hold_static_ci"]
        lines.append(f"  P(hold, static) = {record['p_hold_static']:.4f}  (95% CI {lo:.4f} .. "
                     f"{hi:.4f}; object mass {record['mass_kg']:.3f} kg, six gravity directions "
                     f"and the lift, the hand's effort limits)")
    return lines


def evaluation_record(evaluation, *, sigma, noise: str, model, spec_file, samples: int,
                      seed: int, engine: str, friction: float | None = None) -> dict:
    """One evaluation's keys in ``evaluate --json`` and ``report --json``, whichever robot
    ran: its noise (``sigma`` and the distribution ``noise``, or the ``--noise-spec`` file
    ``spec_file`` and its ``model``: the model's joint distribution, file and settings),
    draws, seed and engine, P(FC) and its interval, ``friction`` where given, Q nominal and
    Q's moments (NaN as null), the error (nominal - mean) and the outcome counts
    (``evaluation``: a :class:`~kinegrasp_env.montecarlo.evaluate.GraspEvaluation`)."""
    from kinegrasp_env.sampling.noise_spec import spec_of

    def finite(value):
        return None if isinstance(value, float) and math.isnan(value) else value

    e = evaluation
    return {"sigma": sigma, "noise": noise if model is None else model.kind,
            **({} if model is None else {"noise_spec": str(spec_file),
                                         "noise_model": spec_of(model)}),
            "samples": samples, "seed": seed, "engine": engine,
            "p_fc": e.p_fc, "p_fc_ci": list(e.ci),
            **({} if friction is None else {"friction": friction}),
            "q_nominal": finite(e.q_nominal), "q_mean": finite(e.q_mean),
            "q_var": finite(e.q_std ** 2), "q_std": finite(e.q_std),
            "q_skew": finite(e.q_skew), "error": finite(e.q_nominal - e.q_mean),
            "outcomes": e.counts}
