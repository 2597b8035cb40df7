"""Run every ``benchmarks/bench_*.py`` and print a summary.

Each benchmark module has ``main(argv) -> int`` (0 or None: parity and checks passed); its own output is printed as
it runs. ``--quick`` is passed on to the benchmarks that have that option; the others run with their defaults.

Run: ``python benchmarks/run_all.py [--quick]`` (``make bench``). Exits 1 if any benchmark fails or raises.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
import traceback
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parent


def run_benchmark(path: Path, argv: list[str]) -> tuple[str, float]:
    """Import ``path`` and call its ``main(argv)``; return a status word and the wall time in seconds."""
    start = time.perf_counter()
    try:
        spec = importlib.util.spec_from_file_location(path.stem, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[path.stem] = module
        spec.loader.exec_module(module)
        code = module.main(list(argv))
    except SystemExit as exit_:
        code = exit_.code
    except Exception:  # a broken benchmark is reported and the others still run
        traceback.print_exc()
        code = "error"
    status = "ok" if code in (0, None) else ("error" if code == "error" else f"failed ({code})")
    return status, time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small runs, for the benchmarks that offer --quick")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    paths = sorted(BENCHMARKS.glob("bench_*.py"))
    results = []
    for path in paths:
        bench_argv = ["--quick"] if args.quick and '"--quick"' in path.read_text() else []
        print(f"=== {path.name} {' '.join(bench_argv)}".rstrip(), flush=True)
        status, seconds = run_benchmark(path, bench_argv)
        results.append((path.name, status, seconds))
        print(flush=True)
    print("=== summary")
    width = max((len(name) for name, _, _ in results), default=10)
    for name, status, seconds in results:
        print(f"{name:<{width}}  {status:<12} {seconds:8.1f} s")
    return 0 if all(status == "ok" for _, status, _ in results) else 1


if __name__ == "__main__":
    sys.exit(main())
