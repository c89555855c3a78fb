// SPDX-License-Identifier: MIT
// The 3D view's mesh tiles (docs/tiles.md): P/tiles/mesh/index.json and its glTF tiles, loaded
// by view. viewer3d.js calls PitmapTiles.attach once it has its scene; the tiles then follow
// the camera. Read over HTTP only: a page opened from a file (file://) may not read other
// files, so there the view keeps the report's decimated mesh and says how to serve the folder.
//
// The rule (evaluated whenever the camera has moved, and after each tile arrives), with s the
// index's tile size, d the distance from the camera to the tile's box (0 inside it) and
// near = s H / (2 tan(fov / 2) minPixels) the distance beyond which the tile's edge would span
// fewer than minPixels of the view's H pixels:
// - wanted: its box grown by s/4 on every side intersects the view frustum, and d <= near;
// - loaded: the wanted tiles, nearest first, while the loaded triangles stay within
//   maxTriangles, at most maxFetches requests at a time;
// - unloaded (removed, its GPU buffers freed): a loaded tile whose box grown by s no longer
//   intersects the frustum, or with d > 2 near. Between the two rules a tile stays as it is,
//   so that a small camera move does not load and unload the same tile.
// Far from the camera (or with no tile loaded) the report's decimated mesh shows the survey:
// it is drawn behind the tiles (polygon offset), which cover it where they are loaded.
(function () {
  "use strict";
  const DEFAULTS = { minPixels: 64, maxTriangles: 3000000, maxFetches: 4 };

  // ctx: { scene, camera, canvas, centre (ENU of the view's origin), requestRender(ms),
  //        colourOf(z, out, k), info(text), state (window.pitmapViewer) }; src: the page's
  // data.mesh_tiles ({ index: URL of index.json relative to the page }).
  function attach(ctx, src, options) {
    const rule = Object.assign({}, DEFAULTS, options || {});
    const st = { status: "loading", message: "", count: 0, tileSizeM: 0, rule: rule,
                 loaded: [], requests: [], unloads: 0, triangles: 0, fetching: 0,
                 evaluations: 0 };
    ctx.state.tiles = st;
    if (location.protocol === "file:") {
      st.status = "file";
      st.message = "the mesh tiles (" + src.index + ") are read only when this page is " +
        "served over HTTP, e.g. python3 -m http.server --directory P, then " +
        "http://localhost:8000/report.html";
      ctx.info(st.message);
      return { update: () => {}, state: st };
    }
    const base = new URL(src.index, location.href);
    const tiles = [];        // { name, url, box (view coords), triangles, object, pending }
    const byName = new Map();
    let lastMatrix = null;

    function fail(why) {
      st.status = "error";
      st.message = "mesh tiles: " + why;
      ctx.info(st.message);
    }
    fetch(base).then(r => {
      if (!r.ok) throw new Error(src.index + ": HTTP " + r.status);
      return r.json();
    }).then(index => {
      if (!index || !Array.isArray(index.tiles) || !(index.tile_size_m > 0))
        throw new Error(src.index + ": not a pitmap mesh tile index (no tiles or tile_size_m)");
      const c = ctx.centre;
      for (const t of index.tiles) {
        if (!Array.isArray(t.min_m) || !Array.isArray(t.max_m) || typeof t.file !== "string")
          throw new Error(src.index + ": a tile without file, min_m or max_m");
        const box = new THREE.Box3(
          new THREE.Vector3(t.min_m[0] - c[0], t.min_m[1] - c[1], t.min_m[2] - c[2]),
          new THREE.Vector3(t.max_m[0] - c[0], t.max_m[1] - c[1], t.max_m[2] - c[2]));
        const tile = { name: t.file, url: new URL(t.file, base).href, box: box,
                       triangles: t.triangles || 0, object: null, pending: false };
        tiles.push(tile);
        byName.set(t.file, tile);
      }
      st.count = tiles.length;
      st.tileSizeM = index.tile_size_m;
      st.status = "ready";
      update();
    }).catch(e => fail(e && e.message ? e.message : String(e)));

    const frustum = new THREE.Frustum();
    const viewProjection = new THREE.Matrix4();
    const grown = new THREE.Box3();
    const eye = new THREE.Vector3();
    function intersects(box, margin) {
      grown.copy(box).expandByScalar(margin);
      return frustum.intersectsBox(grown);
    }
    function nearDistance() {
      const h = Math.max(1, ctx.canvas.clientHeight);
      const tanHalf = Math.tan(ctx.camera.fov * Math.PI / 360);
      return st.tileSizeM * h / (2 * tanHalf * rule.minPixels);
    }
    function unload(tile) {
      ctx.scene.remove(tile.object);
      tile.object.traverse(o => {
        if (o.geometry) o.geometry.dispose();
        if (o.material) o.material.dispose();
      });
      tile.object = null;
      st.triangles -= tile.triangles;
      st.unloads += 1;
    }
    function show(tile, gltf) {
      const root = new THREE.Group();
      root.rotation.x = Math.PI / 2;  // glTF y-up (E, U, -N) back to ENU z-up
      root.add(gltf.scene);
      root.position.set(-ctx.centre[0], -ctx.centre[1], -ctx.centre[2]);
      root.updateMatrixWorld(true);
      let triangles = 0;
      root.traverse(o => {
        if (!o.isMesh) return;
        // Coloured by depth as the report's mesh (not by the tile file's own colours, which
        // span the tiles' range): a loaded tile matches the mesh around it.
        const g = o.geometry;
        const a = g.attributes.position, v = new THREE.Vector3();
        const col = new Float32Array(a.count * 3);
        for (let i = 0; i < a.count; ++i) {
          ctx.colourOf(v.set(a.getX(i), a.getY(i), a.getZ(i)).applyMatrix4(o.matrixWorld).z,
                       col, 3 * i);
        }
        g.setAttribute("color", new THREE.BufferAttribute(col, 3));
        if (!g.attributes.normal) g.computeVertexNormals();
        o.material = new THREE.MeshLambertMaterial({ vertexColors: THREE.VertexColors,
                                                     side: THREE.DoubleSide });
        triangles += (g.index ? g.index.count : g.attributes.position.count) / 3;
      });
      tile.triangles = triangles;
      tile.object = root;
      ctx.scene.add(root);
      st.triangles += triangles;
    }
    function load(tile) {
      tile.pending = true;
      st.fetching += 1;
      st.requests.push(tile.name);
      const done = () => {
        tile.pending = false;
        st.fetching -= 1;
        ctx.requestRender(300);
        update(true);
      };
      fetch(tile.url).then(r => {
        if (!r.ok) throw new Error(tile.name + ": HTTP " + r.status);
        return r.arrayBuffer();
      }).then(buffer => new Promise((resolve, reject) => {
        new THREE.GLTFLoader().parse(buffer, "", g => resolve(g), reject);
      })).then(g => {
        show(tile, g);
        done();
      }).catch(e => {
        tile.failed = true;
        fail(tile.name + ": " + (e && e.message ? e.message : String(e)));
        done();
      });
    }

    // The rule above; force: evaluate even if the camera has not moved (a tile arrived).
    function update(force) {
      if (st.status !== "ready" && !(st.status === "error" && tiles.length)) return;
      const cam = ctx.camera;
      cam.updateMatrixWorld();
      viewProjection.multiplyMatrices(cam.projectionMatrix, cam.matrixWorldInverse);
      if (!force && lastMatrix && lastMatrix.equals(viewProjection)) return;
      lastMatrix = viewProjection.clone();
      frustum.setFromMatrix(viewProjection);
      cam.getWorldPosition(eye);
      st.evaluations += 1;
      const s = st.tileSizeM, near = nearDistance();
      const wanted = [];
      for (const t of tiles) {
        const d = t.box.distanceToPoint(eye);
        if (t.object && (!intersects(t.box, s) || d > 2 * near)) unload(t);
        if (!t.object && !t.pending && !t.failed && d <= near && intersects(t.box, s / 4)) {
          wanted.push([d, t]);
        }
      }
      wanted.sort((a, b) => a[0] - b[0]);
      let budget = rule.maxTriangles - st.triangles;
      for (const t of tiles) if (t.pending) budget -= t.triangles;
      for (const [, t] of wanted) {
        if (st.fetching >= rule.maxFetches || t.triangles > budget) break;
        budget -= t.triangles;
        load(t);
      }
      st.loaded = tiles.filter(t => t.object).map(t => t.name);
    }
    st.update = () => update(true);
    // For the browser test: the camera's view-projection matrix (column-major, as three.js
    // keeps it), its position, the near distance and the canvas height the rule used.
    st.view = () => {
      const cam = ctx.camera;
      cam.updateMatrixWorld();
      const m = new THREE.Matrix4().multiplyMatrices(cam.projectionMatrix,
                                                     cam.matrixWorldInverse);
      const p = cam.getWorldPosition(new THREE.Vector3());
      return { viewProjection: m.elements.slice(), eye: [p.x, p.y, p.z],
               near: nearDistance(), height: ctx.canvas.clientHeight,
               centre: ctx.centre.slice() };
    };
    return { update: () => update(false), state: st };
  }

  window.PitmapTiles = { attach: attach, DEFAULTS: DEFAULTS };
})();
