"""ias_gym.grasp."""
