"""How a file was made, as stored with recordings: the package version, the repository revision, the graph and the
command line, with secrets taken out.

A recording is shared more widely than the shell that made it, so its metadata never holds environment variables
or secrets: :func:`recording_metadata` stores no environment, and :func:`redact` replaces with ``REDACTED``

- the value of every launch arg, node param or nested key whose name looks secret (:data:`SECRET_NAME`: token,
  secret, password, passwd, passphrase, api_key/apikey, access_key, private_key, credential(s), auth);
- ``NAME:=VALUE`` and ``--NAME VALUE`` / ``--NAME=VALUE`` words of a command line with such a name;
- anywhere in any string, the values of those args and params and of environment variables with such a name
  (so a secret that reached a param through ``$(arg token)`` or ``$(env GITHUB_TOKEN)`` is gone too), when at
  least :data:`MIN_SECRET_LEN` characters long (shorter ones would hit unrelated text).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
from typing import Any, Iterable, Mapping

from probeless.paths import REPO_ROOT

SECRET_NAME = re.compile(r"token|secret|passw(or)?d|passphrase|api[_-]?key|access[_-]?key|private[_-]?key"
                         r"|credential|auth(?!or)", re.IGNORECASE)
REDACTED = "REDACTED"
MIN_SECRET_LEN = 6


def git_revision() -> str:
    """The repository's HEAD revision (with '+dirty'), or 'unknown' outside a git checkout."""
    try:
        rev = subprocess.run(["git", "-C", str(REPO_ROOT), "rev-parse", "HEAD"], capture_output=True, text=True,
                             timeout=5).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(REPO_ROOT), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return (rev + ("+dirty" if dirty else "")) if rev else "unknown"


def is_secret_name(name: str) -> bool:
    """Whether an arg, param, option or environment variable called ``name`` holds a secret."""
    return bool(SECRET_NAME.search(name))


def env_secrets(env: Mapping[str, str] | None = None) -> set[str]:
    """Values of the environment variables whose names look secret (``os.environ`` by default)."""
    env = os.environ if env is None else env
    return {v for k, v in env.items() if is_secret_name(k) and len(v) >= MIN_SECRET_LEN}


def _named_secrets(obj: Any) -> set[str]:
    """String values stored under secret-looking keys anywhere in a JSON-like tree."""
    found: set[str] = set()
    if isinstance(obj, Mapping):
        for k, v in obj.items():
            if is_secret_name(str(k)) and not isinstance(v, (Mapping, list, tuple)) and v is not None:
                found.add(str(v))
            found |= _named_secrets(v)
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            found |= _named_secrets(v)
    return found


def _redact_tree(obj: Any) -> Any:
    if isinstance(obj, Mapping):
        return {k: REDACTED if is_secret_name(str(k)) and not isinstance(v, (Mapping, list, tuple)) and v is not None
                else _redact_tree(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_redact_tree(v) for v in obj]
    return obj


def redact_argv(argv: Iterable[str]) -> list[str]:
    """``argv`` with the values of secret-looking ``NAME:=VALUE``, ``--NAME=VALUE`` and ``--NAME VALUE`` replaced."""
    out: list[str] = []
    hide_next = False
    for word in argv:
        if hide_next:
            out.append(REDACTED)
            hide_next = False
            continue
        name, sep, _ = word.partition(":=") if ":=" in word else word.partition("=")
        if sep and (":=" in word or name.startswith("-")) and is_secret_name(name):
            out.append(f"{name}{sep}{REDACTED}")
        else:
            hide_next = word.startswith("--") and not sep and is_secret_name(word)
            out.append(word)
    return out


def _argv_secrets(argv: list[str]) -> set[str]:
    """The secret values :func:`redact_argv` hides in ``argv``."""
    return {a[len(b) - len(REDACTED):] for a, b in zip(argv, redact_argv(argv)) if a != b}


def redact(data: Any, argv: Iterable[str] = (), env: Mapping[str, str] | None = None) -> Any:
    """``data`` (a JSON-like tree) with every secret replaced by ``REDACTED`` (the rules in the module doc).

    ``argv``: a command line whose secret values should be removed from ``data`` wherever they appear.
    """
    argv = list(argv)
    secrets = env_secrets(env) | _named_secrets(data) | _argv_secrets(argv)
    secrets = sorted((s for s in secrets if len(s) >= MIN_SECRET_LEN), key=len, reverse=True)
    return _scrub(_redact_tree(data), secrets)


def _scrub(obj: Any, secrets: list[str]) -> Any:
    if isinstance(obj, str):
        for s in secrets:
            obj = obj.replace(s, REDACTED)
        return obj
    if isinstance(obj, Mapping):
        return {_scrub(k, secrets): _scrub(v, secrets) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_scrub(v, secrets) for v in obj]
    return obj


def recording_metadata(plan: Mapping[str, Any], command: str, version: str) -> dict[str, str]:
    """The ``probeless.graph`` metadata record of a recording: the resolved plan (args, nodes, params), version,
    git revision, command line and graph file, secrets redacted (:func:`redact`), no environment variables."""
    import shlex

    try:
        argv = shlex.split(command)
    except ValueError:
        argv = command.split()
    meta = {"plan": plan, "version": version, "git_revision": git_revision(),
            "command": " ".join(shlex.quote(a) for a in redact_argv(argv)), "graph_file": str(plan.get("file") or "")}
    clean = redact(meta, argv)
    return {k: json.dumps(v) if k == "plan" else str(v) for k, v in clean.items()}
