"""Assisting the glove's wearer (issue #14, paper Flow 3): intent recognition, on-line
acquisition."""
