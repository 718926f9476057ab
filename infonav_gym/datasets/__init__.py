"""Loaders for logged real-robot data sets."""

from infonav_gym.datasets.mrclam import MRCLAMDataset, load


class DatasetNotFound(ValueError):
    """An env's dataset directory does not exist here (the data is not shipped): tools that make every registered env
    leave such an env out (``registry.available_envs``), saying so."""


__all__ = ["DatasetNotFound", "MRCLAMDataset", "load"]
