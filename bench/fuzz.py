"""Fuzz the front end for a fixed budget (`make fuzz`).

Runs the hypothesis strategies of tests/test_fuzz_frontend.py (text mutations and
structure mutations of the examples) against the same property: `compile_file`
returns positioned diagnostics and never raises.  Unlike the test suite the run is
random (derandomize off) from a printed seed, so each run explores new inputs and a
failure can be replayed with `--seed`.  A crashing input is shrunk by hypothesis,
written into tests/invalid/ as a new file, and printed: its line in
tests/invalid/EXPECTED is left for a human to write once the bug is fixed.

    python bench/fuzz.py --seconds 300
    python bench/fuzz.py --examples 20000 --seed 1234
"""

from __future__ import annotations

import argparse
import hashlib
import os
import random
import sys
import time
import traceback
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
os.chdir(ROOT)  # model paths in diagnostics are relative to the repository, as in the tests

from hypothesis import HealthCheck, given, seed, settings  # noqa: E402
from hypothesis.errors import HypothesisException  # noqa: E402

from tests.test_fuzz_frontend import check_result, mutated_models, mutated_texts  # noqa: E402

INVALID = ROOT / "tests" / "invalid"
STRATEGIES = {"text": mutated_texts, "structure": mutated_models}
BATCH = 200  # examples per hypothesis run; the budget is checked between runs


class Crash(Exception):
    """The property failed on one input (kept with the input that broke it)."""

    def __init__(self, path: str, text: str, error: BaseException) -> None:
        super().__init__(f"{path}: {type(error).__name__}: {error}")
        self.path, self.text, self.error = path, text, error


def run_batch(strategy: Callable[[], Any], batch_seed: int, examples: int,
              counter: list[int], failing: list[tuple[str, str, BaseException]]) -> None:
    """One hypothesis run; each execution counted; the last failing input kept (the
    shrunk one: hypothesis replays the minimal example last)."""

    @seed(batch_seed)
    @settings(max_examples=examples, deadline=None, derandomize=False, database=None,
              suppress_health_check=list(HealthCheck), print_blob=False)
    @given(strategy())
    def prop(case: tuple[str, str]) -> None:
        counter[0] += 1
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # as pytest runs the suite (filterwarnings)
                check_result(*case)
        except Exception as e:
            failing.append((case[0], case[1], e))
            raise

    prop()


def save_crash(path: str, text: str) -> Path:
    suffix = Path(path).suffix or ".yaml"
    digest = hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()[:10]
    out = INVALID / f"fuzz_{digest}{suffix}"
    out.write_bytes(text.encode("utf-8", "surrogatepass"))
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    budget = p.add_mutually_exclusive_group()
    budget.add_argument("--seconds", type=float, help="run for this long (default 300)")
    budget.add_argument("--examples", type=int, help="run this many inputs")
    p.add_argument("--seed", type=int, help="the seed (default: a random one, printed)")
    args = p.parse_args(argv)
    first_seed = args.seed if args.seed is not None else random.SystemRandom().randrange(2**32)
    seconds = args.seconds if args.seconds is not None or args.examples is not None else 300.0
    print(f"fuzz: seed {first_seed} (replay: python bench/fuzz.py --seed {first_seed} "
          f"{'--examples ' + str(args.examples) if args.examples else f'--seconds {seconds:g}'})",
          flush=True)
    rng = random.Random(first_seed)
    counter = [0]
    per_kind = dict.fromkeys(STRATEGIES, 0)
    start = time.monotonic()
    batches = 0
    while True:
        done = counter[0]
        if args.examples is not None and done >= args.examples:
            break
        if seconds is not None and args.examples is None and time.monotonic() - start >= seconds:
            break
        kind = list(STRATEGIES)[batches % len(STRATEGIES)]
        n = BATCH if args.examples is None else min(BATCH, args.examples - done)
        failing: list[tuple[str, str, BaseException]] = []
        before = counter[0]
        try:
            run_batch(STRATEGIES[kind], rng.randrange(2**32), n, counter, failing)
        except HypothesisException as e:  # a health or usage problem, not a crash of hfsmc
            print(f"fuzz: hypothesis stopped a {kind} batch: {e}", file=sys.stderr)
        except Exception:
            per_kind[kind] += counter[0] - before
            if not failing:
                raise
            path, text, error = failing[-1]
            saved = save_crash(path, text)
            print(f"fuzz: CRASH after {counter[0]} executions ({kind} mutation of {path}):",
                  file=sys.stderr)
            traceback.print_exception(error, file=sys.stderr)
            print(f"fuzz: input written to {os.path.relpath(saved, ROOT)}; add its line to "
                  "tests/invalid/EXPECTED (FILENAME CODE LINE:COL) once hfsmc gives it a "
                  "diagnostic", file=sys.stderr)
            print(f"fuzz: executions {counter[0]} in {time.monotonic() - start:.0f} s: 1 crash")
            return 1
        per_kind[kind] += counter[0] - before
        batches += 1
    elapsed = time.monotonic() - start
    kinds = ", ".join(f"{k} {v}" for k, v in per_kind.items())
    print(f"fuzz: executions {counter[0]} ({kinds}) in {elapsed:.0f} s "
          f"({counter[0] / max(elapsed, 1e-9):.1f}/s): no crash")
    return 0


if __name__ == "__main__":
    sys.exit(main())
