"""The studies behind bench/records/fitting.md: DR-KFS as a loss fitting templates (``study``) and
training reconstruction networks (``network``). They run from a checkout with the lab installed
(``python bench/fit.py``, ``python bench/single_view.py``)."""
