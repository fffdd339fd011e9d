"""``TORCH_OPS``: the contract's array operations (``contract.array_ops.ArrayOps``) in torch,
with which the torch path evaluates the contract's equations."""

from __future__ import annotations

import torch

from ..contract.array_ops import ArrayOps


def _scatter_sum(index: torch.Tensor, values: torch.Tensor, length: int) -> torch.Tensor:
    return values.new_zeros(length).index_add(0, index, values)


def _scatter_max(out: torch.Tensor, index: torch.Tensor, values: torch.Tensor) -> torch.Tensor:
    return out.scatter_reduce_(0, index, values, reduce="amax")


def _take(values: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    return torch.take_along_dim(values, index, dim=-1)


TORCH_OPS = ArrayOps(
    where=torch.where, minimum=torch.minimum, maximum=torch.maximum, clip=torch.clip,
    sign=torch.sign, ceil=torch.ceil, floor=torch.floor, sqrt=torch.sqrt, exp=torch.exp,
    log=torch.log, sigmoid=torch.sigmoid, stack=torch.stack, take=_take,
    scatter_sum=_scatter_sum, scatter_max=_scatter_max, amin=torch.amin, amax=torch.amax,
    argsort=torch.argsort, cumsum=torch.cumsum, power=torch.pow,
)  # fmt: skip
