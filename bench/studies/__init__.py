"""The studies behind bench/records/fitting.md: DR-KFS as a loss fitting templates (``study``) and
training reconstruction networks (``network``). They run from a checkout (``python bench/fit.py``)
and are not installed with the package."""
