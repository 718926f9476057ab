"""Loaders for logged real-robot data sets."""

from infonav_gym.datasets.mrclam import MRCLAMDataset, load

__all__ = ["MRCLAMDataset", "load"]
