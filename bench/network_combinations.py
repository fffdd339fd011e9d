"""The network study's two further losses: all three terms (pixel MSE + w·DR-KFS + w·Chamfer) and
the control without DR-KFS (pixel MSE + w·Chamfer), trained as ``python bench/fit.py --network``
trains its five, and compared with the networks that study committed.

    python bench/network_combinations.py --out bench/fit-network/combinations.json [--quick]

Seven 2,000-step networks do not fit in the study's two hours on 2 cores, so this run trains the
two new ones and, as the proof that the committed rows are comparable, the Chamfer network again:
``train`` seeds the initial weights, the batches and the Chamfer draws from the plan, so at the
same thread count its judged rows must equal the committed ones (``reproduced`` says whether
they do, and by how much they differ). The comparisons then pair the new networks with the
committed pixel MSE, Chamfer and DR-KFS + Chamfer networks. The new networks' reconstructions are
saved beside the study's under ``meshes/<shape>/``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from drkfs_lab.judging.rule import chamfer_ratios
from drkfs_lab.studies.losses import CHAMFER, PIXEL, pixel_with_chamfer, with_both
from drkfs_lab.studies.network import retrained_beside
from drkfs_lab.studies.study import average_ranks, machine, metric_means, pair_shares


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument(
        "--study", type=Path, default=Path("bench/fit-network/results.json"),
        help="the network study's results.json whose networks the new ones are compared with",
    )  # fmt: skip
    parser.add_argument("--quick", action="store_true", help="the quick network plan")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    start = time.perf_counter()
    study = json.loads(args.study.read_text())
    # the study's DR-KFS form and Chamfer weight, chosen on its validation shapes
    form, weight = study["validation"]["form"], study["validation"]["chamfer_weight"]
    three = with_both(form, study["plan"]["pixel_weight"], weight)
    control = pixel_with_chamfer(weight)
    new = retrained_beside(
        study, [three, control], args.quick, args.threads, args.out.parent, print
    )
    table = new["table"]
    names = [*study["plan"]["losses"], three.name, control.name]
    drkfs_with_chamfer = study["plan"]["losses"][-1]
    pairs = {
        f"{three.name} vs {PIXEL}": (three.name, PIXEL),
        f"{three.name} vs {CHAMFER}": (three.name, CHAMFER),
        f"{three.name} vs {control.name}": (three.name, control.name),  # the DR-KFS term
        f"{three.name} vs {drkfs_with_chamfer}": (three.name, drkfs_with_chamfer),  # pixel MSE
        f"{control.name} vs {PIXEL}": (control.name, PIXEL),
        f"{control.name} vs {CHAMFER}": (control.name, CHAMFER),
    }
    results = {
        "command": f"python bench/network_combinations.py --out {args.out}"
        + (" --quick" if args.quick else ""),
        **machine(),
        "lfd": new["lfd"],
        "study": str(args.study),
        "reproduced": new["reproduced"],
        "losses": names,
        "table": table,
        "meshes": new["meshes"],
        "means": metric_means(table, names),
        "mean_rank": average_ranks(table, names),
        "comparisons": pair_shares(table, pairs),
        "chamfer_l1_over_chamfer_trained": chamfer_ratios(table, names),
        "seconds_per_step": new["seconds_per_step"],
        "seconds": time.perf_counter() - start,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
