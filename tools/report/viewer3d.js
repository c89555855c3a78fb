// SPDX-License-Identifier: MIT
// pitmap-report's interactive 3D view (WebGL through three.js, Debian's libjs-three, inlined
// into report.html with this file, so the report needs no network). Reads the JSON in
// #viewer-data (written by pitmap_report.py: the decimated mesh, the trajectories before and
// after SLAM, a subset of the soundings, all in local ENU metres about `centre`) and shows them
// coloured by depth, with orbit or first-person navigation and a distance tool.
// Exposes window.pitmapViewer (ready, frames, triangles, points) for the browser test.
(function () {
  "use strict";
  const el = document.getElementById("viewer3d");
  const info = document.getElementById("viewer3d-info");
  const state = { ready: false, frames: 0, triangles: 0, points: 0, error: null };
  window.pitmapViewer = state;
  if (!el || typeof THREE === "undefined") return;

  function bytes(b64) {
    const s = atob(b64);
    const out = new Uint8Array(s.length);
    for (let i = 0; i < s.length; ++i) out[i] = s.charCodeAt(i);
    return out.buffer;
  }
  const data = JSON.parse(document.getElementById("viewer-data").textContent);
  const canvasTest = document.createElement("canvas");
  if (!(canvasTest.getContext("webgl") || canvasTest.getContext("experimental-webgl"))) {
    info.textContent = "This browser has no WebGL: the 3D view cannot be shown.";
    return;
  }

  // Depth colours: shallow yellow to deep blue, as the report's figures (z is up).
  const [zDeep, zShallow] = data.zlim;
  function colourOf(z, out, k) {
    const t = Math.min(1, Math.max(0, (zShallow - z) / Math.max(1e-6, zShallow - zDeep)));
    out[k] = 0.98 * (1 - t) + 0.08 * t;
    out[k + 1] = 0.9 * (1 - t) + 0.24 * t + 0.32 * Math.sin(Math.PI * t);
    out[k + 2] = 0.24 * (1 - t) + 0.8 * t;
  }
  function coloured(pos) {
    const c = new Float32Array(pos.length);
    for (let k = 0; k < pos.length; k += 3) colourOf(pos[k + 2], c, k);
    return c;
  }

  const W = () => el.clientWidth, H = () => el.clientHeight;
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setSize(W(), H());
  el.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x15191d);
  scene.add(new THREE.AmbientLight(0xffffff, 0.45));
  const sun = new THREE.DirectionalLight(0xffffff, 0.75);
  sun.position.set(-0.4, -0.6, 1.0);
  scene.add(sun);

  const layers = {};
  if (data.mesh) {
    const g = new THREE.BufferGeometry();
    const pos = new Float32Array(bytes(data.mesh.positions));
    g.setAttribute("position", new THREE.BufferAttribute(pos, 3));
    g.setAttribute("color", new THREE.BufferAttribute(coloured(pos), 3));
    g.setIndex(new THREE.BufferAttribute(new Uint32Array(bytes(data.mesh.indices)), 1));
    g.computeVertexNormals();
    const m = new THREE.Mesh(g, new THREE.MeshLambertMaterial({
      vertexColors: THREE.VertexColors, side: THREE.DoubleSide }));
    scene.add(m);
    layers.mesh = m;
    state.triangles = g.index.count / 3;
  }
  if (data.points) {
    const g = new THREE.BufferGeometry();
    const pos = new Float32Array(bytes(data.points));
    g.setAttribute("position", new THREE.BufferAttribute(pos, 3));
    g.setAttribute("color", new THREE.BufferAttribute(coloured(pos), 3));
    const p = new THREE.Points(g, new THREE.PointsMaterial({
      size: 2, sizeAttenuation: false, vertexColors: THREE.VertexColors }));
    scene.add(p);
    layers.points = p;
    state.points = pos.length / 3;
  }
  for (const [key, colour] of [["trajectory_after", 0xffffff], ["trajectory_before", 0xff8c1a]]) {
    if (!data[key]) continue;
    const g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.BufferAttribute(new Float32Array(bytes(data[key])), 3));
    const l = new THREE.Line(g, new THREE.LineBasicMaterial({ color: colour }));
    scene.add(l);
    layers[key] = l;
  }

  // Camera: looking at the survey from the south-west, above.
  const r = data.radius;
  const camera = new THREE.PerspectiveCamera(50, W() / H(), Math.max(0.01, r / 2000), r * 50);
  camera.up.set(0, 0, 1);
  camera.position.set(-0.9 * r, -1.2 * r, 1.0 * r);
  const orbit = new THREE.OrbitControls(camera, renderer.domElement);
  orbit.target.set(0, 0, 0);
  orbit.update();

  // First-person navigation (own): drag to look, W/S forward and back, A/D sideways,
  // R/F up and down; speed scales with the survey's size.
  const fp = { on: false, yaw: 0, pitch: 0, keys: new Set(), drag: null };
  function fpFromCamera() {
    const d = new THREE.Vector3();
    camera.getWorldDirection(d);
    fp.yaw = Math.atan2(d.y, d.x);
    fp.pitch = Math.asin(Math.max(-1, Math.min(1, d.z)));
  }
  function fpApply() {
    const d = new THREE.Vector3(Math.cos(fp.pitch) * Math.cos(fp.yaw),
                                Math.cos(fp.pitch) * Math.sin(fp.yaw), Math.sin(fp.pitch));
    camera.lookAt(camera.position.clone().add(d));
  }
  renderer.domElement.addEventListener("mousedown", e => { if (fp.on) fp.drag = [e.clientX, e.clientY]; });
  window.addEventListener("mouseup", () => { fp.drag = null; });
  window.addEventListener("mousemove", e => {
    if (!fp.on || !fp.drag) return;
    fp.yaw -= 0.004 * (e.clientX - fp.drag[0]);
    fp.pitch = Math.max(-1.5, Math.min(1.5, fp.pitch - 0.004 * (e.clientY - fp.drag[1])));
    fp.drag = [e.clientX, e.clientY];
    fpApply();
  });
  window.addEventListener("keydown", e => { if (fp.on) fp.keys.add(e.key.toLowerCase()); });
  window.addEventListener("keyup", e => fp.keys.delete(e.key.toLowerCase()));
  function fpStep(dt) {
    if (!fp.on || fp.keys.size === 0) return;
    const v = 0.15 * r * dt;
    const f = new THREE.Vector3(Math.cos(fp.yaw), Math.sin(fp.yaw), 0);
    const s = new THREE.Vector3(Math.sin(fp.yaw), -Math.cos(fp.yaw), 0);
    if (fp.keys.has("w")) camera.position.addScaledVector(f, v);
    if (fp.keys.has("s")) camera.position.addScaledVector(f, -v);
    if (fp.keys.has("d")) camera.position.addScaledVector(s, v);
    if (fp.keys.has("a")) camera.position.addScaledVector(s, -v);
    if (fp.keys.has("r")) camera.position.z += v;
    if (fp.keys.has("f")) camera.position.z -= v;
    fpApply();
  }

  // Distance tool: two clicks on the mesh or the soundings.
  const ray = new THREE.Raycaster();
  ray.params.Points.threshold = r / 300;
  const measure = { on: false, picks: [], objects: [] };
  function clearMeasure() {
    for (const o of measure.objects) scene.remove(o);
    measure.objects = [];
    measure.picks = [];
  }
  function marker(p) {
    const g = new THREE.SphereGeometry(r / 250, 12, 8);
    const m = new THREE.Mesh(g, new THREE.MeshBasicMaterial({ color: 0xff2222 }));
    m.position.copy(p);
    scene.add(m);
    measure.objects.push(m);
  }
  let down = null;
  renderer.domElement.addEventListener("pointerdown", e => { down = [e.clientX, e.clientY]; });
  renderer.domElement.addEventListener("pointerup", e => {
    if (!measure.on || !down || Math.hypot(e.clientX - down[0], e.clientY - down[1]) > 4) return;
    const b = renderer.domElement.getBoundingClientRect();
    ray.setFromCamera(new THREE.Vector2(((e.clientX - b.left) / b.width) * 2 - 1,
                                        -((e.clientY - b.top) / b.height) * 2 + 1), camera);
    const targets = [layers.mesh, layers.points].filter(o => o && o.visible);
    const hit = ray.intersectObjects(targets)[0];
    if (!hit) return;
    if (measure.picks.length === 2) clearMeasure();
    measure.picks.push(hit.point.clone());
    marker(hit.point);
    if (measure.picks.length === 2) {
      const [a, c] = measure.picks;
      const g = new THREE.BufferGeometry().setFromPoints([a, c]);
      const l = new THREE.Line(g, new THREE.LineBasicMaterial({ color: 0xff2222 }));
      scene.add(l);
      measure.objects.push(l);
      info.textContent = "distance " + a.distanceTo(c).toFixed(2) + " m (horizontal " +
        Math.hypot(a.x - c.x, a.y - c.y).toFixed(2) + " m, vertical " +
        Math.abs(a.z - c.z).toFixed(2) + " m)";
    } else {
      info.textContent = "distance: click the second point";
    }
  });

  // The controls under the view.
  const bar = document.getElementById("viewer3d-bar");
  function checkbox(label, key) {
    if (!layers[key]) return;
    const l = document.createElement("label");
    const c = document.createElement("input");
    c.type = "checkbox";
    c.checked = true;
    c.addEventListener("change", () => { layers[key].visible = c.checked; });
    l.appendChild(c);
    l.appendChild(document.createTextNode(" " + label + " "));
    bar.appendChild(l);
  }
  checkbox("mesh", "mesh");
  checkbox("soundings", "points");
  checkbox("trajectory after SLAM (white)", "trajectory_after");
  checkbox("trajectory before SLAM (orange)", "trajectory_before");
  function button(label, fn) {
    const b = document.createElement("button");
    b.textContent = label;
    b.addEventListener("click", () => fn(b));
    bar.appendChild(b);
  }
  button("first person", b => {
    fp.on = !fp.on;
    orbit.enabled = !fp.on;
    b.textContent = fp.on ? "orbit" : "first person";
    if (fp.on) {
      fpFromCamera();
      info.textContent = "first person: drag to look, W/S/A/D to move, R/F up and down";
    } else {
      orbit.target.set(0, 0, 0);
      orbit.update();
      info.textContent = "";
    }
  });
  button("measure distance", b => {
    measure.on = !measure.on;
    b.textContent = measure.on ? "stop measuring" : "measure distance";
    if (!measure.on) clearMeasure();
    info.textContent = measure.on ? "distance: click the first point" : "";
  });

  window.addEventListener("resize", () => {
    camera.aspect = W() / H();
    camera.updateProjectionMatrix();
    renderer.setSize(W(), H());
  });
  let last = performance.now();
  function frame(now) {
    fpStep(Math.min(0.1, (now - last) / 1000));
    last = now;
    renderer.render(scene, camera);
    state.frames += 1;
    state.ready = true;
    requestAnimationFrame(frame);
  }
  requestAnimationFrame(frame);
})();
