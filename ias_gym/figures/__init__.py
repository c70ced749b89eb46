"""Reproductions of the paper's figures: data as CSV, a PNG beside it."""
