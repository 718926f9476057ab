"""Multi-robot (PettingZoo) environments."""
