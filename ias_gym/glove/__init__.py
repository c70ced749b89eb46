"""ias_gym.glove."""
