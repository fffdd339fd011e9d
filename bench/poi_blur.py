"""Would blurring the PoI maps help? The shipped nets at the default config, their maps blurred by
a Gaussian of each sigma before the patches are cut, judged on the benchmark's sensitivity, bars
and retrieval sets (``drkfs train``'s metric-stage rows). Evaluation only: the nets are not
retrained with the blur.

    python bench/poi_blur.py --out bench/results/poi_blur.json
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch
from torch import nn

from drkfs_onnx.config import NETS, PipelineConfig
from drkfs_onnx.metric import DRKFS
from drkfs_onnx.training.evaluate import gaussian_blur
from drkfs_onnx.training.metric_stage import benchmark_row, benchmark_set

SIGMAS = (0.0, 1.0, 2.0)  # pixels


class Blurred(nn.Module):
    """A detector whose maps are blurred: (B, 1, S, S) -> (B, 1, S, S)."""

    def __init__(self, detector: nn.Module, sigma: float):
        super().__init__()
        self.detector, self.sigma = detector, sigma

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        return gaussian_blur(self.detector(images), self.sigma)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--quick", action="store_true", help="the benchmark's quick subset")
    args = parser.parse_args()
    torch.set_num_threads(2)
    start = time.perf_counter()
    bench = benchmark_set(args.quick)
    rows = {}
    for nets in NETS:
        for sigma in SIGMAS:
            metric = DRKFS.pretrained(PipelineConfig(nets=nets))
            if sigma:
                metric.detector = Blurred(metric.detector, sigma)
            name = f"{nets} nets, sigma {sigma:g}"
            rows[name] = benchmark_row(metric, bench)
            print(f"{name}: {rows[name]}")
    quick = " --quick" if args.quick else ""
    results = {
        "command": f"python bench/poi_blur.py --out {args.out}{quick}",
        "config": PipelineConfig().to_dict(),
        "rows": rows,
        "seconds": time.perf_counter() - start,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
