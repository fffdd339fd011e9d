"""Would blurring the PoI maps help? The shipped nets at the default config, their maps blurred by
a Gaussian of each sigma before the patches are cut, judged on the benchmark's sensitivity, bars
and retrieval sets (``drkfs train``'s metric-stage rows). Evaluation only: the nets are not
retrained with the blur.

    python bench/poi_blur.py --out bench/results/poi_blur.json
"""

from __future__ import annotations

import torch
from torch import nn

from drkfs_lab.training.metric_stage import benchmark_rows_script
from drkfs_lab.training.net_metrics import gaussian_blur
from drkfs_onnx.contract.config import NETS, PipelineConfig
from drkfs_onnx.metric import DRKFS

SIGMAS = (0.0, 1.0, 2.0)  # pixels


class Blurred(nn.Module):
    """A detector whose maps are blurred: (B, 1, S, S) -> (B, 1, S, S)."""

    def __init__(self, detector: nn.Module, sigma: float):
        super().__init__()
        self.detector, self.sigma = detector, sigma

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        return gaussian_blur(self.detector(images), self.sigma)


def candidates():
    for nets in NETS:
        for sigma in SIGMAS:
            metric = DRKFS.pretrained(PipelineConfig(nets=nets))
            if sigma:
                metric.detector = Blurred(metric.detector, sigma)
            yield f"{nets} nets, sigma {sigma:g}", metric


if __name__ == "__main__":
    benchmark_rows_script(__doc__, "bench/poi_blur.py", candidates)
