"""The one frozen configuration of the DR-KFS pipeline.

Every number that shapes the metric lives here: the torch path, the exported ONNX graphs and the
numpy runtime all read it, and exported models carry it as JSON so that a scorer can refuse a
model built for another configuration.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from typing import Any

NORMALIZATIONS = ("joint", "each", "none")
REDUCTIONS = ("sum", "mean")


@dataclass(frozen=True)
class PipelineConfig:
    """Pipeline numbers; defaults follow the DR-KFS paper and SoftRas.

    Geometry is in a y-up world where a normalised mesh fits the unit sphere. Cameras sit on the
    upper hemisphere at ``camera_distance`` looking at the origin. Screen distances (``sigma``)
    are in normalised device units, where the image spans [-1, 1].
    """

    # Cameras
    num_views: int = 25
    image_size: int = 256
    fov_degrees: float = 50.0
    camera_distance: float = 2.5
    # Soft rasteriser (SoftRas' defaults: sigma 1e-5, gamma 1e-4, probability cut-off 1e-4,
    # background eps 1e-3)
    sigma: float = 1e-5
    gamma: float = 1e-4
    coverage_eps: float = 1e-4
    background_eps: float = 1e-3
    background: float = 0.0
    # Grey Lambertian shading: one directional light fixed in the camera frame (x right, y down,
    # z forward), pointing from the surface towards the light: up, left and behind the camera.
    light_direction: tuple[float, float, float] = (-0.4, -0.6, -0.7)
    ambient: float = 0.3
    diffuse: float = 0.7
    # PoI detector: sum_n delta_n max_m (W_mn * I + b_mn)
    detector_kernel: int = 5
    detector_n: int = 4
    detector_m: int = 4
    # Patches and HardNet
    patch_size: int = 32
    patch_stride: int = 16
    descriptor_dim: int = 128
    descriptor_width: float = 1.0
    # Instance-norm eps of HardNet's input: sqrt(eps) = 0.03 is a contrast floor. With 1e-6 a flat
    # PoI patch was normalised float rounding, and torch and onnxruntime descriptors of
    # near-flat patches differed by 4e-4.
    patch_norm_eps: float = 1e-3

    def __post_init__(self) -> None:
        if self.num_views < 1:
            raise ValueError("num_views must be at least 1")
        if self.image_size < self.patch_size:
            raise ValueError("image_size must be at least patch_size")
        if self.patch_size % 4 != 0:
            raise ValueError("patch_size must be divisible by 4 (two stride-2 convs in HardNet)")
        if self.detector_kernel % 2 != 1:
            raise ValueError("detector_kernel must be odd so PoI maps keep the image size")
        if min(self.sigma, self.gamma, self.coverage_eps, self.background_eps) <= 0:
            raise ValueError("sigma, gamma and the eps values must be positive")
        if not 0 < self.fov_degrees < 180:
            raise ValueError("fov_degrees must be in (0, 180)")
        if self.camera_distance <= 1.0:
            raise ValueError("camera_distance must exceed 1 (the normalised mesh's radius)")
        if self.descriptor_width <= 0:
            raise ValueError("descriptor_width must be positive")
        object.__setattr__(self, "light_direction", tuple(float(v) for v in self.light_direction))

    @property
    def patches_per_side(self) -> int:
        return (self.image_size - self.patch_size) // self.patch_stride + 1

    @property
    def patches_per_view(self) -> int:
        return self.patches_per_side**2

    @property
    def near(self) -> float:
        """Nearest depth a normalised mesh can reach, with room for larger reconstructions."""
        return self.camera_distance - 1.5

    @property
    def far(self) -> float:
        return self.camera_distance + 1.5

    @property
    def coverage_radius(self) -> float:
        """Screen distance beyond which a face's coverage is cut to zero (SoftRas' culling)."""
        return math.sqrt(self.sigma * math.log(1.0 / self.coverage_eps - 1.0))

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PipelineConfig:
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ValueError(f"unknown config keys: {', '.join(unknown)}")
        return cls(**data)

    @classmethod
    def from_json(cls, text: str) -> PipelineConfig:
        return cls.from_dict(json.loads(text))

    def replace(self, **changes: Any) -> PipelineConfig:
        return dataclasses.replace(self, **changes)
