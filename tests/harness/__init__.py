"""What tests share: teams on the in-process bus, fixtures, child-process helpers (tests/README.md)."""
