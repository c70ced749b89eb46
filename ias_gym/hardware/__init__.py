"""ias_gym.hardware."""
