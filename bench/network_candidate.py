"""One DR-KFS + w x Chamfer network trained at a committed network study's seed and judged on its
test shapes beside that study's Chamfer and pixel MSE networks: for a candidate the study's
validation passed over and its results do not hold (a run before ``candidates_on_test``).

    python bench/network_candidate.py --study bench/fit-network/seed1.json \\
        --form "window r0 mean, coarse to fine" --chamfer-weight 3 \\
        --out bench/fit-network/seed1_candidate.json [--quick]

The Chamfer network is trained again as the proof that the committed rows are comparable
(``network.retrained_beside``: ``reproduced``). The candidate's reconstructions are not saved
(the study's own meshes stay the only ones under ``meshes/``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from drkfs_lab.judging.judges import VISUAL
from drkfs_lab.judging.rule import chamfer_ratios, share
from drkfs_lab.studies.losses import CHAMFER, FORMS, PIXEL, with_chamfer
from drkfs_lab.studies.network import retrained_beside
from drkfs_lab.studies.study import machine


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", type=Path, required=True, help="a network study's results")
    parser.add_argument("--form", required=True, choices=sorted(FORMS), help="the DR-KFS form")
    parser.add_argument("--chamfer-weight", type=float, required=True)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--quick", action="store_true", help="the quick network plan")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    start = time.perf_counter()
    study = json.loads(args.study.read_text())
    candidate = with_chamfer(args.form, args.chamfer_weight)
    new = retrained_beside(study, [candidate], args.quick, args.threads, None, print)
    table = new["table"]
    name = candidate.name
    results = {
        "command": f"python bench/network_candidate.py --study {args.study} --form '{args.form}' "
        f"--chamfer-weight {args.chamfer_weight:g} --out {args.out}"
        + (" --quick" if args.quick else ""),
        **machine(),
        "lfd": new["lfd"],
        "study": str(args.study),
        "seed": study["plan"]["seed"],
        "reproduced": new["reproduced"],
        "candidate": name,
        "chosen_by_validation": name in study["plan"]["losses"],
        "validation_share": study["validation"]["shares"].get(name),
        "table": {s: {n: rows[n] for n in (CHAMFER, PIXEL, name)} for s, rows in table.items()},
        "beats_chamfer": share(table, name, CHAMFER, VISUAL),
        "beats_pixel_mse": share(table, name, PIXEL, VISUAL),
        "chamfer_l1_over_chamfer_trained": chamfer_ratios(table, [name])[name],
        "seconds_per_step": new["seconds_per_step"],
        "seconds": time.perf_counter() - start,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")
    for against in ("beats_chamfer", "beats_pixel_mse"):
        print(f"{name} {against}: {results[against]['wins']} of {results[against]['cells']}")


if __name__ == "__main__":
    main()
