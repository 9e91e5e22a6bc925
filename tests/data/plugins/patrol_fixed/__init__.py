"""The patrol mission under the test architecture `fixed` (tests only; no code)."""
