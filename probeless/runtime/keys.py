"""CURVE key pairs of a graph: ``probeless keys generate DIR [--hosts a,b]`` and reading them back.

Layout of a key directory::

    DIR/public/NAME.key           public key of each pair: every file here is an allowed peer
    DIR/private/NAME.key_secret   secret key of each pair (mode 0600, folder 0700)

A node uses the pair named after its host (a name under ``hosts:``) when DIR has one, else the
pair :data:`DEFAULT_KEY`. Every problem with a file raises :class:`~probeless.errors.GraphError`
naming that file.
"""

from __future__ import annotations

import argparse
import os
import shutil
import stat
import tempfile
from pathlib import Path

import zmq
import zmq.auth

from probeless.errors import GraphError

DEFAULT_KEY = "graph"


def public_file(keys_dir: Path, name: str) -> Path:
    """Where the public key of pair ``name`` lives."""
    return Path(keys_dir) / "public" / f"{name}.key"


def secret_file(keys_dir: Path, name: str) -> Path:
    """Where the secret key of pair ``name`` lives."""
    return Path(keys_dir) / "private" / f"{name}.key_secret"


def key_name(keys_dir: Path, host: str | None) -> str:
    """The pair a node on ``host`` uses: the host's own when DIR has it, else :data:`DEFAULT_KEY`."""
    if host and (public_file(keys_dir, host).exists() or secret_file(keys_dir, host).exists()):
        return host
    return DEFAULT_KEY


def generate(keys_dir: Path, names: list[str], force: bool = False) -> list[Path]:
    """Write one key pair per name; secrets 0600. Refuses to overwrite a secret unless ``force``."""
    keys_dir = Path(keys_dir)
    if not zmq.has("curve"):
        raise GraphError("this libzmq has no CURVE support", file=str(keys_dir))
    for name in names:
        if not name or "/" in name or name.startswith("."):
            raise GraphError(f"invalid key name {name!r}", file=str(keys_dir))
        if secret_file(keys_dir, name).exists() and not force:
            raise GraphError("secret key exists; use --force to replace it", file=str(secret_file(keys_dir, name)))
    (keys_dir / "public").mkdir(parents=True, exist_ok=True)
    (keys_dir / "private").mkdir(mode=0o700, parents=True, exist_ok=True)
    os.chmod(keys_dir / "private", 0o700)
    written = []
    with tempfile.TemporaryDirectory(dir=keys_dir / "private") as tmp:  # 0700: the secret is never exposed
        for name in names:
            pub, sec = (Path(p) for p in zmq.auth.create_certificates(tmp, name))
            os.chmod(sec, 0o600)
            shutil.move(pub, public_file(keys_dir, name))
            os.replace(sec, secret_file(keys_dir, name))
            written += [public_file(keys_dir, name), secret_file(keys_dir, name)]
    return written


def load_public(keys_dir: Path, name: str) -> bytes:
    """The z85 public key of pair ``name``; GraphError naming the file when missing or malformed."""
    path = public_file(keys_dir, name)
    return _load(path, secret=False)[0]


def load_pair(keys_dir: Path, name: str) -> tuple[bytes, bytes]:
    """(public, secret) z85 keys of pair ``name`` from its secret file (which holds both)."""
    path = secret_file(keys_dir, name)
    mode = _stat(path).st_mode
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise GraphError(f"secret key file is accessible by others (mode {stat.filemode(mode)}); "
                         f"run chmod 600 on it", file=str(path))
    return _load(path, secret=True)


def allowed_dir(keys_dir: Path) -> Path:
    """The folder of allowed public keys; GraphError when it holds none."""
    folder = Path(keys_dir) / "public"
    if not folder.is_dir() or not any(folder.glob("*.key")):
        raise GraphError("no public keys (*.key) to allow; run `probeless keys generate`", file=str(folder))
    return folder


def key_problems(keys_dir: Path, names: set[str]) -> list[GraphError]:
    """Every problem with the key files that pairs ``names`` need (empty when all are usable)."""
    problems = []
    checks = [lambda: allowed_dir(keys_dir)]
    for name in sorted(names):
        checks += [lambda n=name: load_public(keys_dir, n), lambda n=name: load_pair(keys_dir, n)]
    for check in checks:
        try:
            check()
        except GraphError as exc:
            problems.append(exc)
    return problems


def _stat(path: Path) -> os.stat_result:
    try:
        return path.stat()
    except OSError as exc:
        raise GraphError(f"key file unreadable: {exc.strerror}; run `probeless keys generate`",
                         file=str(path)) from None


def _load(path: Path, secret: bool) -> tuple[bytes, bytes]:
    _stat(path)
    try:
        public, secret_key = zmq.auth.load_certificate(path)
    except (OSError, ValueError) as exc:
        raise GraphError(f"key file unreadable: {exc}", file=str(path)) from None
    if public is None or len(public) != 40 or (secret and (secret_key is None or len(secret_key) != 40)):
        raise GraphError(f"not a CURVE {'secret' if secret else 'public'} key file", file=str(path))
    return public, secret_key


def cmd_keys(ns: argparse.Namespace) -> int:
    """``probeless keys generate DIR``: print what was written."""
    names = [n.strip() for n in ns.hosts.split(",") if n.strip()] if ns.hosts else [DEFAULT_KEY]
    for path in generate(Path(ns.dir), names, force=ns.force):
        print(f"wrote {path}")
    return 0


def add_keys_parser(sub) -> None:
    """Register ``probeless keys generate``."""
    keys = sub.add_parser("keys", help="CURVE key pairs for graphs that span hosts")
    cmds = keys.add_subparsers(dest="keys_command", required=True)
    c = cmds.add_parser("generate", help="write one key pair per host into DIR/public and DIR/private")
    c.add_argument("dir", metavar="DIR")
    c.add_argument("--hosts", metavar="A,B", help=f"one pair per host name (default: one pair {DEFAULT_KEY!r})")
    c.add_argument("--force", action="store_true", help="replace existing secret keys")
    c.set_defaults(func=cmd_keys)
