"""`hil sweep`: many independent runs over a grid or plan of `hil run` choices, on a local process pool,
Dask or Ray, with stable run ids, resumable results and a report.

Modules: `plan` (grid and plan files → points), `configure` (points → validated RunConfigs through
`hil run`'s parser), `runid` (canonical configuration → id), `engines` (inline, local pool, Dask, Ray),
`task` (what a worker runs), `rows` (flattened metrics; the wall-clock ones), `store` (journal and results
files), `execute` (the sweep loop), `progress`, `report` (summary table, HTML page).
"""
