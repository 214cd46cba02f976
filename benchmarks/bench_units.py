"""The cost of the unit hook on request validation (issue 24, pipeflow.schema.units).

    python benchmarks/bench_units.py [--repeats 2000] [--rounds 7]

Every request model converts quantities ({"value", "unit"}) in its validation (a wrap
validator, ``units.validate``).  This times ``SimulationSpec.model_validate`` of the
paper's example four ways, the variants interleaved round by round (the machine is
shared): ``hook off`` (the validator made a pass-through, as before the feature),
``numbers`` (the hook on, plain SI numbers: what every existing request pays; the input
is scanned once and found free of quantities), ``numbers, no skip`` (plain numbers, every
model running ``convert_fields`` as before the skip: the previous ``numbers``) and
``quantities`` (the hook on, the spin in rpm, the length in mm and u0 in mm: pint parses
and converts).  It prints the best microseconds per validation of each and the ratios
against ``hook off``.
"""

from __future__ import annotations

import argparse
import copy
import time
from collections.abc import Callable
from typing import Any

from pipeflow.schema import units
from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec


def per_call(fn: Callable[[], Any], repeats: int) -> float:
    t0 = time.perf_counter()
    for _ in range(repeats):
        fn()
    return (time.perf_counter() - t0) / repeats * 1e6


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--repeats", type=int, default=2000)
    p.add_argument("--rounds", type=int, default=7)
    args = p.parse_args()
    plain = copy.deepcopy(PAPER_EXAMPLE)
    with_units = copy.deepcopy(PAPER_EXAMPLE)
    with_units["rotation"]["omega0"]["value"] = {"value": 954.93, "unit": "rpm"}
    with_units["pipe"]["L"] = {"value": 25, "unit": "mm"}
    with_units["initial"]["u0"] = {"value": 1, "unit": "mm"}
    SimulationSpec.model_validate(with_units)  # pint's registry built once, outside the timing
    real = units.validate
    variants: dict[str, Callable[[type[Any], Any, Callable[[Any], Any]], Any]] = {
        "hook off": lambda model, data, handler: handler(data),
        "numbers": real,
        "numbers, no skip": lambda model, data, handler: handler(units.convert_fields(model, data)),
    }
    best = dict.fromkeys([*variants, "quantities"], float("inf"))
    for _ in range(args.rounds):
        for name, hook in variants.items():
            units.validate = hook  # type: ignore[assignment]
            best[name] = min(
                best[name], per_call(lambda: SimulationSpec.model_validate(plain), args.repeats)
            )
        units.validate = real
        best["quantities"] = min(
            best["quantities"],
            per_call(lambda: SimulationSpec.model_validate(with_units), args.repeats // 10),
        )
    base = best["hook off"]
    print(f"{'variant':<17} {'us/validation':>14} {'/ hook off':>10}")
    for name, us in best.items():
        print(f"{name:<17} {us:>14.1f} {us / base:>10.2f}")


if __name__ == "__main__":
    main()
