"""sha256 from Python's own module, not OpenSSL's `_hashlib`.

`hashlib` loads OpenSSL (≈ 3 MB of RSS) on import; a robot's agent imports the instance digest
and the planning package, and loads no heavy library (tests/test_agent_imports.py). The digest
is the same either way. The module is `_sha256` up to Python 3.11 and `_sha2` from 3.12."""

try:
    from _sha256 import sha256
except ImportError:
    from _sha2 import sha256

__all__ = ["sha256"]
