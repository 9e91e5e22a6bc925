"""The experiment system: `mrta experiment FILE.yaml`, a matrix of reproducible mission runs and
its report. It owns the experiment file (file.py, a typed document), its instances block
(instances.py), one run as any backend starts it (runs.py: a package copy with its overrides, a
run's argv, its row) run here in parallel (api.py, cli.py) or on a Dask cluster
(dask_backend.py), results.csv (results.py) and the report made from that file alone (report.py,
report_md.py, report_plots.py; statistics in stats.py). It starts missions only through the
mission runner's entry point and reads their summary.json back through its schema
(mrta_supervisor.mission); it knows nothing of the live supervisor.
"""
