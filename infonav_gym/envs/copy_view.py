"""``OneCopyView``: what the N = 1 views of an env written once share (its Gymnasium and its PettingZoo view)."""

from __future__ import annotations


class OneCopyView:
    """A view of one copy of ``vector_env`` without autoreset: its config keys, metadata, metrics, traits, rendering
    and, with the vector env's ``planning_model(copy)``, ``planning_model()``: that of its copy.

    A subclass names its vector env (``class MyEnv(SingleEnvView, vector_env=MyVectorEnv)``) and calls
    ``_view_one_copy`` in its ``__init__``; ``metadata_keys`` are the vector env's metadata it shows.
    """

    vector_env: type
    metadata_keys: tuple[str, ...] = ("render_modes", "render_fps")

    def __init_subclass__(cls, vector_env: type | None = None, **kwargs):
        super().__init_subclass__(**kwargs)
        if vector_env is not None:
            cls.vector_env = vector_env
            cls.metadata = {key: vector_env.metadata[key] for key in cls.metadata_keys}
            cls.episode_metrics = vector_env.episode_metrics
            cls.traits = vector_env.traits
            if callable(getattr(vector_env, "planning_model", None)):
                cls.planning_model = _copy_planning_model

    @classmethod
    def default_config(cls) -> dict:
        """A fresh dict of every config key with its default; the constructor's keywords override it."""
        return cls.vector_env.default_config()

    def _view_one_copy(self, render_mode: str | None, config: dict) -> None:
        """Make ``vector``, the one copy (its errors naming this class), and take its config and ``render_mode``."""
        self.vector = self.vector_env.one_copy(type(self).__name__, render_mode, config)
        self.config = self.vector.config
        self.render_mode = render_mode

    def render(self):
        """The copy's frame (see the vector env's ``render``); a warning and None without a render mode."""
        return self.vector.render()

    def close(self):
        self.vector.close()


def _copy_planning_model(self):
    """The env's planning model (its vector env's of its one copy), for look-ahead agents (``PlannerAgent``)."""
    return self.vector.planning_model(0)
