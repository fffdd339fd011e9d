"""The rule that chooses a loss from judged reconstructions: the share of cells where one
loss's results beat another's, and the candidate that beats the baseline on the most visual
cells (``drkfs choose-loss``, and the network study that found the rule)."""

from __future__ import annotations

import numpy as np

from .judges import VISUAL, better

CHAMFER = "Chamfer"  # the Chamfer loss's name in the studies' tables: the usual baseline


def share(table: dict, challenger: str, against: str, metrics: tuple[str, ...]) -> dict:
    """The (problem, metric) cells where ``challenger``'s result beats ``against``'s; a cell
    either side lacks (volumetric IoU of an open mesh, LFD where it is not installed) is not
    counted."""
    cells = {
        f"{p}/{m}": better(m, rows[challenger][m], rows[against][m])
        for p, rows in table.items()
        for m in metrics
        if rows[challenger].get(m) is not None and rows[against].get(m) is not None
    }
    wins = sum(cells.values())
    return {"wins": wins, "cells": len(cells), "share": wins / len(cells), "cell_wins": cells}


def brief_share(table: dict, challenger: str, against: str, metrics: tuple[str, ...]) -> dict:
    """``share`` without its cell list: {"wins", "cells", "share"}."""
    return {k: v for k, v in share(table, challenger, against, metrics).items() if k != "cell_wins"}


def chamfer_ratios(table: dict, losses, against: str = CHAMFER) -> dict[str, float | None]:
    """Each loss's Chamfer-L1 over ``against``'s (the Chamfer result's), averaged over the
    table's rows; None where ``against`` matches some row's target exactly."""
    if any(rows[against]["Chamfer-L1"] == 0 for rows in table.values()):
        return dict.fromkeys(losses)
    return {
        loss: float(
            np.mean(
                [rows[loss]["Chamfer-L1"] / rows[against]["Chamfer-L1"] for rows in table.values()]
            )
        )
        for loss in losses
    }


def choose(table: dict, candidates: list[str], baseline: str) -> dict:
    """The network study's rule for a loss: of ``candidates``, the one whose results beat
    ``baseline``'s on the most visual cells of ``table`` (shape -> loss -> judged row); a tie
    goes to the earlier candidate -> {"chosen", "shares": candidate -> {"wins", "cells",
    "share"}, "chamfer_l1_ratio": candidate -> its Chamfer-L1 over the baseline's}."""
    shares = {name: brief_share(table, name, baseline, VISUAL) for name in candidates}
    return {
        "chosen": max(candidates, key=lambda n: shares[n]["share"]),  # max keeps the first
        "shares": shares,
        "chamfer_l1_ratio": chamfer_ratios(table, candidates, baseline),
    }
