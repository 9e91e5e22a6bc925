"""ping_app: a third-party application for mrta-zenoh (see examples/ping_app/README.md)."""
