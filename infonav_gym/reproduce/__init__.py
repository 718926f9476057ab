"""Regenerate the paper's figures from the environments (``infonav reproduce``)."""

FIGURES = ("fig3", "fig5", "fig6")


def paper_label(agent: str) -> str:
    """The paper's name of a robot, numbered from 1: ``robot_0`` -> ``#1``."""
    return f"#{int(agent.rpartition('_')[2]) + 1}"
