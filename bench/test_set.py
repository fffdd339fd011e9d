"""Score the frozen test set once, at a metric version's release, never to choose anything.

The set is drkfs_lab.benchmark.test_set.

    python bench/test_set.py --release drkfs-1.1 --out bench/results/test_set.json

The release named must be the newest version (``PipelineConfig()``'s), and the results file must
not hold it yet: a version's test figures are written once, at its release, and kept. Every
named version stands beside it (their rows say what the release changed on pairs nobody chose
on), with pixel MSE, Chamfer-L1 and LFD where it is installed. A version or peer an earlier
release scored is kept from that release (``"kept"``: the set is frozen, and so are a version's
config and a peer's): the rest are scored, and the previous release's version again, so the
seconds a pair compare within one run.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from datetime import date
from pathlib import Path

import drkfs_onnx
from drkfs_lab.benchmark import test_set
from drkfs_lab.benchmark.methods import DrkfsOnnx, build_methods
from drkfs_lab.benchmark.run import (
    TIER_PAIRS,
    as_they_come_checks,
    score_with_peers,
    tier_accuracy,
)
from drkfs_lab.training.run import git_commit
from drkfs_onnx.contract.versions import LATEST, VERSIONS, metric_config

PEERS = ("pixel MSE", "Chamfer-L1", "LFD")


def release_error(release: str, out: Path, bench) -> str | None:
    """Why ``release`` may not be scored into ``out`` on ``bench`` (None when it may)."""
    if release != LATEST:
        return f"--release {release}: only the newest version ({LATEST}) is released"
    if out.is_file() and release in json.loads(out.read_text()).get("releases", {}):
        return f"{out}: {release} was scored at its release; its test figures are kept"
    found = test_set.digest(bench)
    if found != test_set.DIGEST:
        return f"the test set moved (digest {found[:12]}, frozen {test_set.DIGEST[:12]})"
    return None


def kept_from(releases: dict) -> dict[str, str]:
    """Each version and peer an earlier release scored -> the latest release that scored it,
    but the latest release's own version (scored again beside the new one, for the seconds)."""
    kept = {}
    for release, entry in releases.items():
        kept.update({name: release for name in entry["methods"] if name in (*VERSIONS, *PEERS)})
    if releases:
        kept.pop(list(releases)[-1], None)
    return kept


def summary(bench, values: dict[int, float | None]) -> dict:
    """A method's figures on the test set: the tier shares of both groups, with their pair
    counts, and the assets' checks."""
    shares = {}
    for group in (test_set.TIERS_GROUP, test_set.ASSETS_GROUP):
        found = tier_accuracy(bench, values, group)
        shares[group] = {pair: found[pair] for pair in TIER_PAIRS} | {"pairs": found["pairs"]}
    checks = as_they_come_checks(bench, values, test_set.ASSETS_GROUP)["all"]
    return {**shares, "asset_checks": {name: row["share"] for name, row in checks.items()}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--release", required=True, help="the version released (the newest)")
    parser.add_argument("--out", type=Path, required=True, help="the results' JSON (appended)")
    parser.add_argument("--threads", type=int, default=2, help="onnxruntime and renderer threads")
    parser.add_argument(
        "--work", type=Path, default=Path("runs/test_set"), help="graphs exported if not shipped"
    )
    args = parser.parse_args()
    start = time.perf_counter()
    bench = test_set.build()
    error = release_error(args.release, args.out, bench)
    if error:
        sys.exit(f"error: {error}")
    results = json.loads(args.out.read_text()) if args.out.is_file() else {}
    earlier = results.get("releases", {})
    kept = kept_from(earlier)
    wanted = [name for name in [*VERSIONS, *PEERS] if name not in kept]
    methods = [DrkfsOnnx(name, metric_config(name), None, args.threads)
               for name in VERSIONS if name in wanted]  # fmt: skip
    methods += [m for m in build_methods(args.work / "models", args.threads)
                if set(m.outputs) & set(wanted)]  # fmt: skip
    scores, costs, notes = score_with_peers(bench, methods, print, wanted)
    scored = {n: v for n, v in scores.comparisons.items() if n in wanted}
    rows = {name: earlier[release]["methods"][name] for name, release in kept.items()}
    values = {name: earlier[release]["values"][name] for name, release in kept.items()}
    for name, found in scored.items():
        rows[name] = {**summary(bench, found), "seconds_per_pair": costs[name]["seconds_per_pair"]}
        values[name] = {
            f"{c.base}/{c.label}": found.get(i) for i, c in enumerate(bench.comparisons)
        }
    kept_notes = {n: earlier[r]["peers"][n] for n, r in kept.items() if n in earlier[r]["peers"]}
    release = {
        "command": f"python bench/test_set.py --release {args.release} --out {args.out} "
        f"--threads {args.threads} --work {args.work}",
        "package": drkfs_onnx.__version__,
        "commit": git_commit(),
        "date": date.today().isoformat(),
        "platform": platform.platform(),
        "threads": args.threads,
        "peers": {**kept_notes, **notes},
        "kept": kept,
        "methods": {name: rows[name] for name in [*VERSIONS, *PEERS] if name in rows},
        "values": {name: values[name] for name in [*VERSIONS, *PEERS] if name in values},
        "seconds": time.perf_counter() - start,
    }
    results["set"] = {
        "digest": test_set.DIGEST,
        "tier_seeds": list(test_set.TIER_SEEDS),
        "asset_seeds": list(test_set.ASSET_SEEDS),
        "labels": {f"{c.base}/{c.label}": [c.group, c.kind] for c in bench.comparisons},
    }
    results.setdefault("releases", {})[args.release] = release
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")
    for name, row in release["methods"].items():
        cells = [
            row[g][p] for g in (test_set.TIERS_GROUP, test_set.ASSETS_GROUP) for p in TIER_PAIRS
        ]
        print(f"{name:22}" + "".join(f"{'n/a' if c is None else f'{c:.3f}':>8}" for c in cells))


if __name__ == "__main__":
    main()
