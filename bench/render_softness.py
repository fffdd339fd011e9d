"""Do the shipped nets still rank structure on softer renders? The default's nets and match at
each (sigma, gamma) of the soft rasteriser, judged on the benchmark's sensitivity, bars and
retrieval sets (``drkfs train``'s metric-stage rows). Evaluation only: the nets were trained at
the scoring renderer (sigma 1e-5, gamma 1e-4) and are not retrained. ``PipelineConfig.training()``
is the row sigma 1e-4, gamma 0.1.

    python bench/render_softness.py --out bench/results/render_softness.json
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from drkfs_onnx.config import PipelineConfig
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.training.metric_stage import benchmark_row, benchmark_set

SOFTNESS = (  # (sigma, gamma): the scoring renderer, then softer coverage, then softer depth
    (1e-5, 1e-4),
    (1e-4, 1e-4),
    (1e-4, 1e-2),
    (1e-4, 3e-2),
    (1e-4, 1e-1),
    (3e-4, 1e-1),
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--quick", action="store_true", help="the benchmark's quick subset")
    args = parser.parse_args()
    torch.set_num_threads(2)
    start = time.perf_counter()
    bench = benchmark_set(args.quick)
    training = PipelineConfig.training()
    rows = {}
    for sigma, gamma in SOFTNESS:
        config = PipelineConfig(sigma=sigma, gamma=gamma)
        name = f"sigma {sigma:g}, gamma {gamma:g}" + (
            " (training config)" if config == training else ""
        )
        rows[name] = benchmark_row(DRKFS.pretrained(config), bench)
        print(f"{name}: {rows[name]}", flush=True)
    quick = " --quick" if args.quick else ""
    results = {
        "command": f"python bench/render_softness.py --out {args.out}{quick}",
        "config": PipelineConfig().to_dict(),
        "rows": rows,
        "seconds": time.perf_counter() - start,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
