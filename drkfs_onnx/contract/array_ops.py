"""One convention for code that runs on numpy arrays and torch tensors alike: it is written with
arithmetic and indexing, which both share, and takes an ``ArrayOps`` as ``ops`` for every other
step. ``NUMPY_OPS`` is here; ``TORCH_OPS`` is the torch renderer's (``render.torch_ops``), so
this module, like the rest of the contract, imports no torch."""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np


class ArrayOps(NamedTuple):
    """An array module's operations, under the names both modules give them, except:

    - ``sigmoid(x)``;
    - ``take(values, index)``: gather along the last axis, broadcasting the others;
    - ``scatter_sum(index, values, length)``: a (length,) array of the values summed by index;
    - ``scatter_max(out, index, values)``: ``out`` raised in place to the values' maximum by
      index, and returned;
    - ``amin``/``amax``/``argsort``/``cumsum(x, axis)``: along one axis, positionally;
    - ``power(x, p)``: x to the float power p.
    """

    where: Callable
    minimum: Callable
    maximum: Callable
    clip: Callable
    sign: Callable
    ceil: Callable
    floor: Callable
    sqrt: Callable
    exp: Callable
    log: Callable
    sigmoid: Callable
    stack: Callable
    take: Callable
    scatter_sum: Callable
    scatter_max: Callable
    amin: Callable
    amax: Callable
    argsort: Callable
    cumsum: Callable
    power: Callable


def _sigmoid(x: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore"):
        return 1.0 / (1.0 + np.exp(-x))


def _scatter_sum(index: np.ndarray, values: np.ndarray, length: int) -> np.ndarray:
    return np.bincount(index, values, minlength=length)


def _scatter_max(out: np.ndarray, index: np.ndarray, values: np.ndarray) -> np.ndarray:
    np.maximum.at(out, index, values)
    return out


def _power(x: np.ndarray, p: float) -> np.ndarray:
    # numpy's float32 power runs about 25 times slower than a square root and a product, which
    # give the power 1.5 exactly enough (torch's keeps the power: x * sqrt(x) has no gradient
    # at 0)
    return x * np.sqrt(x) if p == 1.5 else x**p


def _take(values: np.ndarray, index: np.ndarray) -> np.ndarray:
    if index.ndim <= values.ndim and all(n == 1 for n in index.shape[:-1]):
        # one index row for every row of values (a mesh's faces in each view): a plain take,
        # about 4 times faster than take_along_axis, which builds an index array per axis
        return np.take(values, index.reshape(-1), axis=-1)
    return np.take_along_axis(values, index, axis=-1)


NUMPY_OPS = ArrayOps(
    where=np.where, minimum=np.minimum, maximum=np.maximum, clip=np.clip, sign=np.sign,
    ceil=np.ceil, floor=np.floor, sqrt=np.sqrt, exp=np.exp, log=np.log, sigmoid=_sigmoid,
    stack=np.stack, take=_take, scatter_sum=_scatter_sum, scatter_max=_scatter_max,
    amin=np.amin, amax=np.amax, argsort=np.argsort, cumsum=np.cumsum, power=_power,
)  # fmt: skip
