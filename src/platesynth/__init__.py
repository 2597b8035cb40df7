"""platesynth: synthetic multi-well plate assay images, realism metrics and segmentation."""

__version__ = "0.1.0"
