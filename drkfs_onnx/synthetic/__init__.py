"""Synthetic data made by code: procedural shapes (``shapes``), their mild and structural
variants (``variants``) and the bundled example chairs (``examples``). The training sets, the
benchmark and the fitting study draw from here with disjoint seeds."""
