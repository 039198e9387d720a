"""The learned correspondence provider (the only package importing torch), on three floors:

- :mod:`ancsh.learned.network` -- PointNet++, the ANCSH and direct-voting networks, their config and weights files;
- :mod:`ancsh.learned.inference` -- joint voting, :class:`~ancsh.learned.inference.provider.LearnedProvider`,
  ``predict`` on a depth image, the calibrated confidence (-> network);
- :mod:`ancsh.learned.training` -- losses, training arrays, the training loop (-> inference, network);

with :mod:`ancsh.learned.devices` and :mod:`ancsh.learned.distributed` beneath all three.
"""
