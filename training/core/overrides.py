"""`--config key=value` overrides of named ml_collections configs ({"ppo": ..., "env": ...}): the one parser
for the CLI's experiments and the recipes' stage diffs."""
from __future__ import annotations

import ast
from typing import Mapping, Sequence

_BOOL_WORDS = {"true": True, "false": False}   # the JSON / YAML spellings, typed out of habit
# Env settings of the toy preset (PPO's and DAgger's; applied where the task's config has the key): 0.4 s
# episodes and a small bank of host-precomputed fallen starts.
TOY_ENV_OVERRIDES = {"episode_length": 20, "fallen.bank_starts": 2}


def _parse_value(text: str):
    """Python literal if it is one (1e-4, (0.4, 0.4, 0.2), True; also true / false), else the text itself."""
    word = text.strip().lower()
    if word in _BOOL_WORDS:
        return _BOOL_WORDS[word]
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return text


def apply_overrides(configs: Mapping[str, object], pairs: Sequence[str]) -> None:
    """Apply `key=value` overrides to named ConfigDicts, e.g. {"ppo": ..., "env": ...}.

    `ppo.learning_rate=1e-4` names the config; a bare `learning_rate=1e-4` goes to the one config that
    has the key (an error when none or several have it). Dotted keys reach nested fields
    (`env.noise_config.level=0.5`)."""
    for pair in pairs:
        if "=" not in pair:
            raise ValueError(f"--config {pair!r}: expected key=value")
        key, text = pair.split("=", 1)
        head = key.split(".", 1)[0]
        if head in configs and "." in key:
            targets = [(head, key.split(".", 1)[1])]
        else:
            targets = [(name, key) for name, cfg in configs.items() if _has_path(cfg, key)]
            if len(targets) != 1:
                where = "no config" if not targets else " and ".join(n for n, _ in targets)
                raise ValueError(f"--config {key}: found in {where}; prefix it with one of {sorted(configs)}.")
        name, path = targets[0]
        cfg = configs[name]
        if not _has_path(cfg, path):
            raise ValueError(f"--config {key}: {name} config has no field {path!r}")
        *parents, leaf = path.split(".")
        for p in parents:
            cfg = cfg[p]
        try:
            cfg[leaf] = _parse_value(text)
        except (TypeError, ValueError) as e:
            raise ValueError(f"--config {key}={text}: {e}") from e


def _has_path(cfg, path: str) -> bool:
    for part in path.split("."):
        try:
            if part not in cfg:
                return False
        except TypeError:
            return False
        cfg = cfg[part]
    return True
