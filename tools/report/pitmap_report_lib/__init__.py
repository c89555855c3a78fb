# SPDX-License-Identifier: MIT
"""The pieces of pitmap-report (tools/report/pitmap_report.py, the command line):

  util      logging, errors, HTML helpers (Esc, Num, Table), time conversion
  loaders   products-folder inputs: summary.json, scores.json, trajectory CSV, PLY
  rasters   gridding (mean/max rasters, hole filling, mesh rasterising, decimation) and
            figure making (PNG files and data URIs)
  sections_survey, sections_geometry, sections_hydro, sections_clean, sections_viewer,
  sections_stats
            each report section's HTML, as mixins of report.Report
  report    the Report: products + sections -> one HTML page
  gltf      the .glb container check and the glTF page (--view-gltf) with the same viewer
"""
