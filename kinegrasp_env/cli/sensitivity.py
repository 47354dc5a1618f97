"""``kinegrasp sensitivity``: which source of error limits a grasp's P(FC).

P(FC) with every source of a noise spec, with each source alone and with all but one, and the
first-order and total Sobol indices of force closure per source, with bootstrap intervals
(:mod:`kinegrasp_env.toolkit.sensitivity`); optionally a bar chart.
"""

from __future__ import annotations

import json
import sys

from kinegrasp_env.cli.common import (
    CLIError,
    add_engine_arg,
    add_object_arg,
    engine_name,
    grasp_index_help,
    output_file,
    parse_seed,
    positive_int,
    reported,
    shipped_grasp,
)


def cmd_sensitivity(args) -> int:
    from kinegrasp_env.montecarlo.evaluate import check_noise_engine
    from kinegrasp_env.sampling.noise_model import NoiseSpecError
    from kinegrasp_env.sampling.noise_spec import load_noise_model

    with reported(NoiseSpecError):
        model = load_noise_model(args.noise_spec)
    if not model.sources:
        raise CLIError(f"--noise-spec {args.noise_spec}: the model has no source of error; "
                       "nothing to analyze")
    samples = positive_int(args.samples, "--samples", low=2)
    bootstrap = positive_int(args.bootstrap, "--bootstrap", low=0)
    seed = parse_seed(args.seed)
    index, grasp = shipped_grasp(args.object, args.grasp)
    engine = engine_name(args.engine)
    with reported(ValueError):
        check_noise_engine(model, engine)
    if args.plot:
        output_file(args.plot, "--plot")
    result = _analyze(grasp, model, samples, seed, engine, bootstrap)
    payload = result.to_json()
    if args.json:
        print(json.dumps(payload))
    else:
        print(result.table())
    if args.plot:  # after the results: a failing figure is a warning, the results stand
        from kinegrasp_env.toolkit.plots import plot_sensitivity, safe_figure

        title = (f"{args.object} grasp {index}: P(FC) {result.p_all:.3f} with every source, "
                 f"{samples} draws per setting")
        written = safe_figure(lambda: plot_sensitivity(payload, args.plot, title=title),
                              args.plot)
        if written is not None and not args.json:
            print(f"plot written to {args.plot}")
    return 0


def _analyze(grasp, model, samples: int, seed: int, engine: str, bootstrap: int):
    """The analysis with a progress bar on stderr (one step per setting)."""
    from tqdm import tqdm

    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.toolkit.sensitivity import analyze

    runner = make_engine(engine, grasp.object)
    bar = tqdm(total=None, desc="sensitivity", unit="setting", file=sys.stderr, disable=None)

    def progress(done: int, total: int) -> None:
        bar.total = total
        bar.update(done - bar.n)

    try:
        return analyze(grasp, model, samples, seed, engine=runner, bootstrap=bootstrap,
                       progress=progress)
    finally:
        bar.close()
        runner.close()


def add_commands(sub) -> None:
    """Register ``sensitivity``."""
    p = sub.add_parser("sensitivity", help="P(FC) per source of error and Sobol indices of "
                       "force closure: which source limits a grasp")
    add_object_arg(p, "spray_flask", "catalog object")
    p.add_argument("--grasp", default="0", help=grasp_index_help())
    p.add_argument("--noise-spec", required=True,
                   help="YAML or JSON noise model: joints, hand, palm, object, friction "
                   "(or preset: dexnet); every source present is a factor")
    p.add_argument("--samples", default="1000",
                   help="draws per setting (the analysis runs about 2 + 3 x sources settings)")
    p.add_argument("--bootstrap", default="1000",
                   help="bootstrap resamples of the Sobol intervals (0: none)")
    p.add_argument("--seed", default="0", help="random seed (an integer >= 0)")
    add_engine_arg(p)
    p.set_defaults(engine="fast")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", help="write a PNG bar chart of the indices and P(FC)s")
    p.set_defaults(func=cmd_sensitivity)
