"""Do the shipped nets still rank structure on softer renders? The default's nets and match at
each (sigma, gamma) of the soft rasteriser, judged on the benchmark's sensitivity, bars and
retrieval sets (``drkfs train``'s metric-stage rows). Evaluation only: the nets were trained at
the scoring renderer (sigma 1e-5, gamma 1e-4) and are not retrained. ``PipelineConfig.training()``
is the row sigma 1e-4, gamma 0.1.

    python bench/render_softness.py --out bench/results/render_softness.json
"""

from __future__ import annotations

from drkfs_lab.training.metric_stage import benchmark_rows_script
from drkfs_onnx.contract.config import PipelineConfig
from drkfs_onnx.metric import DRKFS

SOFTNESS = (  # (sigma, gamma): the scoring renderer, then softer coverage, then softer depth
    (1e-5, 1e-4),
    (1e-4, 1e-4),
    (1e-4, 1e-2),
    (1e-4, 3e-2),
    (1e-4, 1e-1),
    (3e-4, 1e-1),
)


def candidates():
    training = PipelineConfig.training()
    for sigma, gamma in SOFTNESS:
        config = PipelineConfig(sigma=sigma, gamma=gamma)
        name = f"sigma {sigma:g}, gamma {gamma:g}"
        yield name + (" (training config)" if config == training else ""), DRKFS.pretrained(config)


if __name__ == "__main__":
    benchmark_rows_script(__doc__, "bench/render_softness.py", candidates)
