"""
Reading the results folders into tables: episode rows and per-run metrics, the one pass over the paper sweep's rows,
the studies the launcher ran, and the context every section gets.
"""
