"""Anticipatory ping-pong pipeline: from raw lab recordings to a simulated robot."""

__version__ = "0.1.0"
