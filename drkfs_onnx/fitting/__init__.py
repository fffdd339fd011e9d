"""Fitting meshes with DR-KFS and other losses (``drkfs fit``; needs the ``torch`` extra)."""
