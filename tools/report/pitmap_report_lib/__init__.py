# SPDX-License-Identifier: MIT
"""The pieces of pitmap-report (tools/report/pitmap_report.py, the command line):

  util      logging, errors, HTML helpers (esc, num, table, strip_paths), time conversion
  loaders   products-folder inputs: summary.json, scores.json, trajectory CSV, PLY, and
            Products, the loaded folder every section is a function of
  rasters   gridding (mean/max rasters, hole filling, mesh rasterising, decimation) and
            figure making (PNG files and data URIs)
  maps      GeoTIFF rasters and world points in the projected CRS; grid ticks, scale bar,
            north arrow, grid convergence
  sections_client, sections_survey, sections_geometry, sections_hydro, sections_clean,
  sections_viewer, sections_stats
            the sections: functions of the products returning HTML
  report    which section goes on which page (report.html for the client,
            report_engineering.html) and the pages themselves
  pdf       report.pdf through headless Chromium's print to PDF (--pdf)
  gltf      the .glb container check and the glTF page (--view-gltf) with the same viewer
"""
