"""The speed-against-accuracy benchmark (``drkfs bench``, torch extra): variant sets written to
disk, DR-KFS variants and point/volume/pixel baselines on the same inputs, the stability table and
the chart."""
