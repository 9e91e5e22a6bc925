"""rqt_mrta: architecture and application files, registry, templates, wizard, launch files."""
