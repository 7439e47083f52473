"""pgi renderer: progressive light transport in participating media."""

__version__ = "0.1.0"
