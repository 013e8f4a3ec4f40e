"""The benchmark harness: run matrix (settings), isolated solves (runner), Parquet results,
executors (serial, local processes, Dask), statistics, plots and the Markdown report.
"""
