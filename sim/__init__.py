"""MuJoCo simulation of press-and-release palpation: a stream source for palpate.core."""
