"""Judging reconstructions by metrics no loss computes, and choosing a loss by them
(``drkfs choose-loss``; needs the ``torch`` extra)."""
