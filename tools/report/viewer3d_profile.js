// SPDX-License-Identifier: MIT
// The cross-section tool's geometry and plot for viewer3d.js (inlined into the page before
// it): the profile of a mesh along the vertical plane through two points, the soundings in a
// corridor about that plane, and a 2D plot of both with axes in metres. Pure functions of
// their arguments, no three.js: exposed as window.PitmapProfile.
//
// Frames: the viewer's coordinates, z up, metres. A profile station is (s, z): s is the
// horizontal distance from A along A->B, z the height in the viewer's frame (the caller adds
// its offset to show heights in the products' local ENU frame).
(function () {
  "use strict";

  // The horizontal line A->B: origin, unit direction u, unit normal n (u turned +90 deg about
  // z) and length. A and B closer than 1 mm apart give null (no plane).
  function lineOf(a, b) {
    const dx = b[0] - a[0], dy = b[1] - a[1];
    const length = Math.hypot(dx, dy);
    if (!(length > 1e-3)) return null;
    const ux = dx / length, uy = dy / length;
    return { ax: a[0], ay: a[1], ux: ux, uy: uy, nx: -uy, ny: ux, length: length };
  }

  // Cuts a triangle mesh with the vertical plane through the line A->B and keeps the part
  // between A and B. positions: xyz per vertex (already in the viewer's frame); index:
  // three vertex numbers per triangle, or null for a non-indexed mesh (three vertices per
  // triangle). Returns the cut as segments [s0, z0, s1, z1, ...] (Float64Array): one per
  // triangle that the plane crosses. Each vertex's signed distance d to the plane decides
  // its side (d >= 0 or d < 0); an edge whose ends lie on different sides is cut at
  // t = d_p / (d_p - d_q), so a triangle with a vertex on the plane is cut once, not twice.
  function meshSection(positions, index, line) {
    const nv = positions.length / 3;
    const d = new Float64Array(nv), s = new Float64Array(nv);
    for (let i = 0; i < nv; ++i) {
      const x = positions[3 * i] - line.ax, y = positions[3 * i + 1] - line.ay;
      d[i] = x * line.nx + y * line.ny;
      s[i] = x * line.ux + y * line.uy;
    }
    const out = [];
    const nt = index ? index.length / 3 : nv / 3;
    const cut = [0, 0, 0, 0];
    for (let t = 0; t < nt; ++t) {
      const v = index ? [index[3 * t], index[3 * t + 1], index[3 * t + 2]]
                      : [3 * t, 3 * t + 1, 3 * t + 2];
      const side0 = d[v[0]] >= 0, side1 = d[v[1]] >= 0, side2 = d[v[2]] >= 0;
      if (side0 === side1 && side1 === side2) continue;
      let k = 0;
      for (let e = 0; e < 3; ++e) {
        const p = v[e], q = v[(e + 1) % 3];
        if ((d[p] >= 0) === (d[q] >= 0)) continue;
        const f = d[p] / (d[p] - d[q]);
        cut[k++] = s[p] + f * (s[q] - s[p]);
        cut[k++] = positions[3 * p + 2] + f * (positions[3 * q + 2] - positions[3 * p + 2]);
      }
      const seg = clipToLine(cut, line.length);
      if (seg) out.push(seg[0], seg[1], seg[2], seg[3]);
    }
    return Float64Array.from(out);
  }

  // The part of segment [s0, z0, s1, z1] with 0 <= s <= length, or null.
  function clipToLine(c, length) {
    let [s0, z0, s1, z1] = c;
    if (s0 > s1) [s0, z0, s1, z1] = [s1, z1, s0, z0];
    if (s1 < 0 || s0 > length) return null;
    const lerp = (s) => (s1 - s0 > 1e-12 ? z0 + (z1 - z0) * (s - s0) / (s1 - s0) : z0);
    const a = Math.max(0, s0), b = Math.min(length, s1);
    return [a, lerp(a), b, lerp(b)];
  }

  // Soundings within halfWidth of the plane and between A and B: [s, z, s, z, ...].
  function corridorPoints(positions, line, halfWidth) {
    const out = [];
    for (let i = 0; i < positions.length; i += 3) {
      const x = positions[i] - line.ax, y = positions[i + 1] - line.ay;
      if (Math.abs(x * line.nx + y * line.ny) > halfWidth) continue;
      const s = x * line.ux + y * line.uy;
      if (s >= 0 && s <= line.length) out.push(s, positions[i + 2]);
    }
    return Float64Array.from(out);
  }

  // Tick step for about `count` ticks over `span`: 1, 2 or 5 times a power of ten.
  function tickStep(span, count) {
    const raw = span / Math.max(1, count);
    const p = Math.pow(10, Math.floor(Math.log10(raw)));
    for (const m of [1, 2, 5]) if (m * p >= raw) return m * p;
    return 10 * p;
  }

  const kMargin = { left: 64, right: 16, top: 12, bottom: 44 };

  // Draws a profile into a 2D canvas. p: { length, mesh (segments), points ([s, z]), zOffset
  // (added to every z for the labels), water (height of the water surface or null),
  // trueScale (1 m across = 1 m up) }. Returns the plot's mapping { sx, sz, toS, toZ,
  // exaggeration } for the hover read-out.
  function draw(canvas, p) {
    const ratio = window.devicePixelRatio || 1;
    const w = canvas.clientWidth, h = canvas.clientHeight;
    canvas.width = Math.round(w * ratio);
    canvas.height = Math.round(h * ratio);
    const g = canvas.getContext("2d");
    g.setTransform(ratio, 0, 0, ratio, 0, 0);
    g.fillStyle = "#ffffff";
    g.fillRect(0, 0, w, h);
    let zMin = Infinity, zMax = -Infinity;
    for (const arr of [p.mesh, p.points]) {
      for (let i = 1; i < arr.length; i += 2) {
        zMin = Math.min(zMin, arr[i]);
        zMax = Math.max(zMax, arr[i]);
      }
    }
    if (p.water !== null && isFinite(zMin)) zMax = Math.max(zMax, p.water);
    if (!isFinite(zMin)) { zMin = -1; zMax = 1; }
    const pad = Math.max(0.5, 0.05 * (zMax - zMin));
    zMin -= pad;
    zMax += pad;
    const pw = w - kMargin.left - kMargin.right, ph = h - kMargin.top - kMargin.bottom;
    let sSpan = p.length;
    if (p.trueScale) {  // one scale for both axes: widen whichever range is short
      const need = (zMax - zMin) * pw / ph;
      if (need > sSpan) sSpan = need;
      else {
        const mid = (zMin + zMax) / 2, half = sSpan * ph / pw / 2;
        zMin = mid - half;
        zMax = mid + half;
      }
    }
    const sx = pw / sSpan, sz = ph / (zMax - zMin);
    const X = (s) => kMargin.left + s * sx;
    const Y = (z) => kMargin.top + (zMax - z) * sz;

    // Grid, ticks and labels (heights shown in the products' frame: z + zOffset).
    g.font = "12px sans-serif";
    g.strokeStyle = "#dde3e8";
    g.fillStyle = "#333";
    g.lineWidth = 1;
    const sStep = tickStep(sSpan, pw / 90);
    g.textAlign = "center";
    g.textBaseline = "top";
    for (let s = 0; s <= sSpan + 1e-9; s += sStep) {
      g.beginPath();
      g.moveTo(X(s), kMargin.top);
      g.lineTo(X(s), kMargin.top + ph);
      g.stroke();
      g.fillText(formatTick(s, sStep), X(s), kMargin.top + ph + 4);
    }
    const zStep = tickStep(zMax - zMin, ph / 40);
    g.textAlign = "right";
    g.textBaseline = "middle";
    const zFirst = Math.ceil((zMin + p.zOffset) / zStep) * zStep - p.zOffset;
    for (let z = zFirst; z <= zMax + 1e-9; z += zStep) {
      g.beginPath();
      g.moveTo(kMargin.left, Y(z));
      g.lineTo(kMargin.left + pw, Y(z));
      g.stroke();
      g.fillText(formatTick(z + p.zOffset, zStep), kMargin.left - 6, Y(z));
    }
    g.strokeStyle = "#555";
    g.strokeRect(kMargin.left, kMargin.top, pw, ph);
    g.textAlign = "center";
    g.textBaseline = "bottom";
    g.fillText("distance along A \u2192 B (m)", kMargin.left + pw / 2, h - 2);
    g.save();
    g.translate(14, kMargin.top + ph / 2);
    g.rotate(-Math.PI / 2);
    g.textBaseline = "middle";
    g.fillText("height z (m, local ENU)", 0, 0);
    g.restore();

    g.save();
    g.beginPath();
    g.rect(kMargin.left, kMargin.top, pw, ph);
    g.clip();
    if (p.water !== null) {
      g.strokeStyle = "#2a6f97";
      g.setLineDash([6, 4]);
      g.beginPath();
      g.moveTo(X(0), Y(p.water));
      g.lineTo(X(sSpan), Y(p.water));
      g.stroke();
      g.setLineDash([]);
    }
    g.fillStyle = "rgba(230, 120, 20, 0.75)";
    for (let i = 0; i < p.points.length; i += 2) {
      g.fillRect(X(p.points[i]) - 1.5, Y(p.points[i + 1]) - 1.5, 3, 3);
    }
    g.strokeStyle = "#111";
    g.lineWidth = 1.6;
    g.beginPath();
    for (let i = 0; i < p.mesh.length; i += 4) {
      g.moveTo(X(p.mesh[i]), Y(p.mesh[i + 1]));
      g.lineTo(X(p.mesh[i + 2]), Y(p.mesh[i + 3]));
    }
    g.stroke();
    g.restore();
    return {
      toS: (px) => (px - kMargin.left) / sx,
      toZ: (py) => zMax - (py - kMargin.top) / sz,
      sx: sx, sz: sz, exaggeration: sz / sx,
    };
  }

  function formatTick(v, step) {
    const digits = Math.max(0, -Math.floor(Math.log10(step) + 1e-9));
    return (Math.abs(v) < step / 1e6 ? 0 : v).toFixed(digits);
  }

  // The mesh segment nearest to (s, z) within maxDistance (in the plot's pixels, through the
  // mapping m), as { s, z, slopeDeg } at the nearest point, or null.
  function nearest(mesh, s, z, m, maxDistance) {
    let best = null, bestD = maxDistance;
    for (let i = 0; i < mesh.length; i += 4) {
      const ax = mesh[i] * m.sx, ay = mesh[i + 1] * m.sz;
      const bx = mesh[i + 2] * m.sx, by = mesh[i + 3] * m.sz;
      const px = s * m.sx, py = z * m.sz;
      const vx = bx - ax, vy = by - ay;
      const len2 = vx * vx + vy * vy;
      const f = len2 > 0 ? Math.max(0, Math.min(1, ((px - ax) * vx + (py - ay) * vy) / len2)) : 0;
      const dist = Math.hypot(ax + f * vx - px, ay + f * vy - py);
      if (dist < bestD) {
        bestD = dist;
        const ds = mesh[i + 2] - mesh[i], dz = mesh[i + 3] - mesh[i + 1];
        best = { s: mesh[i] + f * ds, z: mesh[i + 1] + f * dz,
                 slopeDeg: Math.atan2(Math.abs(dz), Math.abs(ds)) * 180 / Math.PI };
      }
    }
    return best;
  }

  window.PitmapProfile = { lineOf, meshSection, corridorPoints, draw, nearest, tickStep };
})();
