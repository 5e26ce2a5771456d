"""masonry_nscd: masonry walls block by block with Non-Smooth Contact Dynamics."""

__version__ = "0.1.0"
