"""Where SB3's training time goes on cooperative_exploration_v0 (observe_gains=True) with a hyperparameter block:
the share of the update, the collection and update rates, and the bare torch rate of the same networks' update.

    python scripts/training_phases.py [--hyperparams FILE]   # default: the shipped block (agents/hyperparams/ppo.yml)
"""

import argparse
import time

import torch

from agents.base import torch_threads
from agents.ppo import build_model, load_hyperparameters

ENV_ID, CONFIG = "cooperative_exploration_v0", {"observe_gains": True}


def bare_update_rate(model, repeats: int = 30) -> float:
    """Samples/s of a forward, backward and Adam step of the policy's networks alone, on random minibatches."""
    policy, batch = model.policy, model.batch_size
    observations = torch.randn(batch, *model.observation_space.shape)
    optimizer = torch.optim.Adam(policy.parameters(), lr=3e-4)
    start = time.perf_counter()
    for _ in range(repeats):
        logits = policy.action_net(policy.mlp_extractor.forward_actor(policy.extract_features(observations)))
        values = policy.value_net(policy.mlp_extractor.forward_critic(policy.extract_features(observations)))
        loss = logits.logsumexp(-1).mean() + values.pow(2).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    return repeats * batch / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hyperparams", help="a ppo.yml-style file with a cooperative_exploration_v0 block")
    args = parser.parse_args()
    block = load_hyperparameters(ENV_ID, args.hyperparams)
    with torch_threads():
        model = build_model(ENV_ID, 0, None, block, CONFIG)
        rollout, seconds = model.n_steps * model.n_envs, {"update": 0.0}
        update = model.train

        def timed_update():
            start = time.perf_counter()
            update()
            seconds["update"] += time.perf_counter() - start

        model.train = timed_update
        model.learn(rollout)  # warm-up: the compiled kernels, the first episodes
        seconds["update"], before, start = 0.0, model.num_timesteps, time.perf_counter()
        model.learn(3 * rollout, reset_num_timesteps=False)
        total, steps = time.perf_counter() - start, model.num_timesteps - before
        bare = bare_update_rate(model)
    epochs = model.n_epochs
    print(f"{steps / total:.0f} robot steps/s; the update {seconds['update'] / total:.0%} of the time")
    print(f"collection {steps / (total - seconds['update']):.0f} robot steps/s")
    print(f"update {epochs * steps / seconds['update']:.0f} sample-epochs/s; bare torch {bare:.0f} samples/s")


if __name__ == "__main__":
    main()
