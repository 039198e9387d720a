"""Using a trained network: joint voting, the learned correspondence provider, ``predict`` on a depth image,
and the calibrated confidence of a prediction."""
