#!/usr/bin/env python3
"""Saved benchmark baselines: catch a regression by comparing runs, never by a timed test.

After `cargo bench` (any subset), criterion leaves each benchmark's latest estimates in
`$CARGO_TARGET_DIR/criterion/**/new/` (default `target/`). This script

  save NAME      records the median of every benchmark found there in
                 `benches/baselines/NAME.json` (commit it, e.g. one per release);
  compare NAME   prints, per benchmark, the baseline median, the latest median and their
                 ratio (latest / baseline: above 1 is slower), worst first, and exits 1
                 when a ratio exceeds --fail-above (default: never).

Medians are in nanoseconds per iteration. Compare runs made on the same machine.
"""

import argparse
import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BASELINES = ROOT / "benches" / "baselines"


def latest_medians():
    criterion = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target")) / "criterion"
    medians = {}
    for estimates in criterion.glob("**/new/estimates.json"):
        folder = estimates.parent
        meta = json.loads((folder / "benchmark.json").read_text())
        medians[meta["full_id"]] = json.loads(estimates.read_text())["median"]["point_estimate"]
    return medians


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("action", choices=["save", "compare"])
    parser.add_argument("name", help="baseline name, e.g. the release (0.5.0)")
    parser.add_argument("--fail-above", type=float, default=None, help="exit 1 if any ratio exceeds this")
    args = parser.parse_args()
    medians = latest_medians()
    if not medians:
        sys.exit("no criterion results found: run `cargo bench` first")
    path = BASELINES / f"{args.name}.json"
    if args.action == "save":
        BASELINES.mkdir(parents=True, exist_ok=True)
        saved = json.loads(path.read_text()) if path.exists() else {}
        saved.update(medians)
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(dict(sorted(saved.items())), indent=1) + "\n")
        tmp.replace(path)
        print(f"{len(medians)} benchmarks saved in {path.relative_to(ROOT)}")
        return
    if not path.exists():
        sys.exit(f"no baseline {path.relative_to(ROOT)}")
    baseline = json.loads(path.read_text())
    rows = sorted(
        ((latest / baseline[name], name, baseline[name], latest) for name, latest in medians.items() if name in baseline),
        reverse=True,
    )
    print(f"{'ratio':>7}  {'baseline ns':>14}  {'latest ns':>14}  benchmark")
    for ratio, name, base, latest in rows:
        print(f"{ratio:7.3f}  {base:14.1f}  {latest:14.1f}  {name}")
    missing = sorted(set(medians) - set(baseline))
    if missing:
        print(f"not in the baseline: {', '.join(missing)}")
    if args.fail_above is not None and rows and rows[0][0] > args.fail_above:
        sys.exit(1)


if __name__ == "__main__":
    main()
