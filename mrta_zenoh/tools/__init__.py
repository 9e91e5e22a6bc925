"""The generic tools' api (echo, record, router): what their `mrta` verbs call."""
