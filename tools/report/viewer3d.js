// SPDX-License-Identifier: MIT
// pitmap's interactive 3D view (WebGL through three.js r111, Debian's libjs-three, inlined into
// the page with OrbitControls, VRButton, GLTFLoader and viewer3d_profile.js, so the page needs
// no network). Reads the JSON in #viewer-data, written by pitmap-report: in report.html the
// decimated mesh, the trajectories before and after SLAM and a subset of the soundings, in
// local ENU metres about `centre_enu_m`; in a glTF page (pitmap-report --view-gltf) a .glb
// (base64) instead. Shows them coloured by depth, with orbit or first-person navigation, a
// distance tool, a cross-section tool (profile of the mesh and the soundings along a vertical
// plane), WebXR "enter VR" at real size, and "open glTF..." for a local .glb.
//
// Frames: the view's coordinates are the products' local ENU (x east, y north, z up, metres)
// minus view.centre. glTF files are y-up, (E, U, -N) in pitmap's mesh.glb; they are turned
// back to z-up on loading.
//
// The view is drawn on demand: when the camera moves, for a moment after any input (a click, a
// key, a checkbox, the wheel), after a glTF is shown and while "enter VR" or the first-person
// keys are on. A report left open does not redraw a mesh of millions 60 times a second.
// Exposes window.pitmapViewer for the browser test: ready, frames (drawn), ticks (the animation
// loop's turns, drawn or not), triangles, points, gltf
// (name, status, message, triangles), equipment (per model placed from the page's data: name,
// status "placed" or "error", message, centre [x, y, z] of its box in the products' ENU, on the
// mesh or at the height given), profile (the last cross-section), crossSection(a, b)
// (a cross-section between two ENU points [x, y], as the tool's two clicks make it) and
// openGltf(arrayBuffer, name) (what "open glTF..." does with a file's bytes), setCamera(position,
// target) (ENU) and tiles (the mesh tiles loaded by view, viewer3d_tiles.js).
(function () {
  "use strict";
  const el = document.getElementById("viewer3d");
  const info = document.getElementById("viewer3d-info");
  const problem = document.getElementById("viewer3d-problem");
  const state = { ready: false, frames: 0, ticks: 0, triangles: 0, points: 0, error: null,
                  gltf: null, profile: null, equipment: [] };
  window.pitmapViewer = state;
  if (!el || typeof THREE === "undefined") return;

  function bytes(b64) {
    const s = atob(b64);
    const out = new Uint8Array(s.length);
    for (let i = 0; i < s.length; ++i) out[i] = s.charCodeAt(i);
    return out.buffer;
  }
  function showProblem(text) {
    state.error = text;
    if (!problem) return;
    problem.textContent = text;
    problem.hidden = !text;
  }
  const data = JSON.parse(document.getElementById("viewer-data").textContent);
  const canvasTest = document.createElement("canvas");
  if (!(canvasTest.getContext("webgl") || canvasTest.getContext("experimental-webgl"))) {
    info.textContent = "This browser has no WebGL: the 3D view cannot be shown.";
    return;
  }

  // What the view is framed on; a glTF page learns it from the file once loaded.
  const view = {
    centre: data.centre_enu_m || null,  // ENU of the view's origin
    radius: data.radius || 1,           // half the survey's largest extent, m
    zlim: data.zlim || [-1, 1],         // deep and shallow ends of the depth colours
  };

  // Depth colours: shallow yellow to deep blue, as the report's figures (z is up).
  function colourOf(z, out, k) {
    const [zDeep, zShallow] = view.zlim;
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
    // Pushed back in depth: where mesh tiles are loaded (viewer3d_tiles.js) they cover it.
    const m = new THREE.Mesh(g, new THREE.MeshLambertMaterial({
      vertexColors: THREE.VertexColors, side: THREE.DoubleSide,
      polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 4 }));
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
  let track = null;  // the vehicle's track (after SLAM when there is one): the water surface
  for (const [key, colour] of [["trajectory_after", 0xffffff], ["trajectory_before", 0xff8c1a]]) {
    if (!data[key]) continue;
    const pos = new Float32Array(bytes(data[key]));
    const g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.BufferAttribute(pos, 3));
    const l = new THREE.Line(g, new THREE.LineBasicMaterial({ color: colour }));
    scene.add(l);
    layers[key] = l;
    if (!track) track = pos;
  }
  // Height of the water surface in view coordinates: the track's median height, or null.
  const waterZ = (() => {
    if (!track || track.length < 3) return null;
    const z = [];
    for (let i = 2; i < track.length; i += 3) z.push(track[i]);
    z.sort((a, b) => a - b);
    return z[z.length >> 1];
  })();

  // Camera: looking at the survey from the south-west, above.
  const camera = new THREE.PerspectiveCamera(50, W() / H(), 0.01, 100);
  camera.up.set(0, 0, 1);
  const orbit = new THREE.OrbitControls(camera, renderer.domElement);
  // Drawing on demand: requestRender() draws the next frame, an input keeps drawing 300 ms.
  let renderWanted = true;
  let renderUntil = 0;
  function requestRender(ms) {
    renderWanted = true;
    if (ms) renderUntil = Math.max(renderUntil, performance.now() + ms);
  }
  orbit.addEventListener("change", () => requestRender());
  for (const type of ["pointerdown", "pointermove", "pointerup", "wheel", "keydown", "keyup",
                      "click", "change", "input", "touchstart", "touchmove", "resize"]) {
    window.addEventListener(type, () => requestRender(300), { capture: true, passive: true });
  }
  const ray = new THREE.Raycaster();
  function frameView(centre, radius) {
    view.radius = Math.max(1, radius);
    const r = view.radius;
    camera.near = Math.max(0.01, r / 2000);
    camera.far = r * 50;
    camera.position.set(centre.x - 0.9 * r, centre.y - 1.2 * r, centre.z + 1.0 * r);
    camera.updateProjectionMatrix();
    orbit.target.copy(centre);
    orbit.update();
    ray.params.Points.threshold = r / 300;
  }
  frameView(new THREE.Vector3(0, 0, 0), view.radius);

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
  window.addEventListener("keydown", e => {
    if (fp.on && e.target === document.body) fp.keys.add(e.key.toLowerCase());
  });
  window.addEventListener("keyup", e => fp.keys.delete(e.key.toLowerCase()));
  function fpStep(dt) {
    if (!fp.on || fp.keys.size === 0) return;
    const v = 0.15 * view.radius * dt;
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

  // The surfaces the tools work on: the report's mesh and a loaded glTF, when shown.
  function surfaceMeshes() {
    const out = [];
    if (layers.mesh && layers.mesh.visible) out.push(layers.mesh);
    if (layers.gltf && layers.gltf.visible) {
      layers.gltf.traverse(o => { if (o.isMesh && o.visible) out.push(o); });
    }
    return out;
  }
  // A mesh's vertices in view coordinates (its world matrix applied) and its triangles.
  function worldTriangles(mesh) {
    mesh.updateMatrixWorld(true);
    const a = mesh.geometry.attributes.position;
    const pos = new Float32Array(a.count * 3);
    const v = new THREE.Vector3();
    for (let i = 0; i < a.count; ++i) {
      v.set(a.getX(i), a.getY(i), a.getZ(i)).applyMatrix4(mesh.matrixWorld);
      pos[3 * i] = v.x;
      pos[3 * i + 1] = v.y;
      pos[3 * i + 2] = v.z;
    }
    return { positions: pos, index: mesh.geometry.index ? mesh.geometry.index.array : null };
  }

  // The tools' two clicks: "distance" or "section", on the mesh, a glTF or the soundings.
  const tool = { kind: null, picks: [], objects: [] };
  function clearTool() {
    requestRender();
    for (const o of tool.objects) scene.remove(o);
    tool.objects = [];
    tool.picks = [];
  }
  function marker(p) {
    const g = new THREE.SphereGeometry(view.radius / 250, 12, 8);
    const m = new THREE.Mesh(g, new THREE.MeshBasicMaterial({ color: 0xff2222 }));
    m.position.copy(p);
    scene.add(m);
    tool.objects.push(m);
  }
  // Tool lines are drawn over everything: a profile lies on the surface it was cut from.
  function line3d(points, colour, segments) {
    const g = new THREE.BufferGeometry().setFromPoints(points);
    const material = new THREE.LineBasicMaterial({ color: colour, depthTest: false });
    const l = segments ? new THREE.LineSegments(g, material) : new THREE.Line(g, material);
    l.renderOrder = 1;
    scene.add(l);
    tool.objects.push(l);
    return l;
  }
  let down = null;
  renderer.domElement.addEventListener("pointerdown", e => { down = [e.clientX, e.clientY]; });
  renderer.domElement.addEventListener("pointerup", e => {
    if (!tool.kind || !down || Math.hypot(e.clientX - down[0], e.clientY - down[1]) > 4) return;
    const b = renderer.domElement.getBoundingClientRect();
    ray.setFromCamera(new THREE.Vector2(((e.clientX - b.left) / b.width) * 2 - 1,
                                        -((e.clientY - b.top) / b.height) * 2 + 1), camera);
    const targets = surfaceMeshes();
    if (layers.points && layers.points.visible) targets.push(layers.points);
    const hit = ray.intersectObjects(targets, false)[0];
    if (!hit) return;
    if (tool.picks.length === 2) clearTool();
    tool.picks.push(hit.point.clone());
    marker(hit.point);
    const what = tool.kind === "distance" ? "distance" : "cross-section";
    if (tool.picks.length < 2) {
      info.textContent = what + ": click the second point";
      return;
    }
    const [a, c] = tool.picks;
    if (tool.kind === "distance") {
      line3d([a, c], 0xff2222);
      info.textContent = "distance " + a.distanceTo(c).toFixed(2) + " m (horizontal " +
        Math.hypot(a.x - c.x, a.y - c.y).toFixed(2) + " m, vertical " +
        Math.abs(a.z - c.z).toFixed(2) + " m)";
    } else {
      cutProfile(a, c);
    }
  });

  // Cross-section: the mesh cut by the vertical plane through A and B, and the soundings
  // within the corridor, as a 2D profile under the view and as lines in 3D.
  const profileBox = document.getElementById("viewer3d-profile");
  const profileCanvas = document.getElementById("viewer3d-profile-canvas");
  const profileCaption = document.getElementById("viewer3d-profile-caption");
  const profileReadout = document.getElementById("viewer3d-profile-readout");
  const corridorInput = document.getElementById("viewer3d-corridor");
  const trueScale = document.getElementById("viewer3d-truescale");
  let profile = null;  // { a, b, line, mesh, points, plot }
  let profileLines = [];  // the profile's 3D lines (redrawn when the corridor changes)
  function corridor() {
    const w = parseFloat(corridorInput ? corridorInput.value : "0.5");
    return isFinite(w) && w >= 0 ? w : 0.5;
  }
  function cutProfile(a, b) {
    requestRender();
    const P = window.PitmapProfile;
    const line = P.lineOf([a.x, a.y], [b.x, b.y]);
    if (!line) {
      info.textContent = "cross-section: the two points are less than 1 mm apart; click again";
      return;
    }
    const parts = surfaceMeshes().map(m => {
      const t = worldTriangles(m);
      return P.meshSection(t.positions, t.index, line);
    });
    const mesh = new Float64Array(parts.reduce((n, p) => n + p.length, 0));
    parts.reduce((at, p) => { mesh.set(p, at); return at + p.length; }, 0);
    const pts = layers.points && layers.points.visible
      ? P.corridorPoints(layers.points.geometry.attributes.position.array, line, corridor())
      : new Float64Array(0);
    profile = { a: a, b: b, line: line, mesh: mesh, points: pts, plot: null };
    const ends = [];
    for (let i = 0; i < mesh.length; i += 2) {
      ends.push(new THREE.Vector3(a.x + line.ux * mesh[i], a.y + line.uy * mesh[i], mesh[i + 1]));
    }
    for (const o of profileLines) scene.remove(o);
    profileLines = [line3d([new THREE.Vector3(a.x, a.y, a.z), new THREE.Vector3(b.x, b.y, b.z)],
                           0xff2222)];
    if (ends.length) profileLines.push(line3d(ends, 0xffe14d, true));
    drawProfile();
    const zc = view.centre ? view.centre[2] : 0;
    const enu = (p) => [p.x + (view.centre ? view.centre[0] : 0),
                        p.y + (view.centre ? view.centre[1] : 0), p.z + zc];
    state.profile = {
      a: enu(a), b: enu(b), length: line.length, corridor: corridor(),
      segments: Array.from(mesh, (v, i) => (i % 2 ? v + zc : v)),
      points: pts.length / 2,
    };
    info.textContent = "cross-section " + line.length.toFixed(2) + " m: " + mesh.length / 4 +
      " mesh segments, " + pts.length / 2 + " soundings within \u00b1" + corridor() + " m" +
      (mesh.length ? "" : " (the line misses the mesh)");
  }
  function drawProfile() {
    if (!profile || !profileBox) return;
    profileBox.hidden = false;
    const zc = view.centre ? view.centre[2] : 0;
    profile.plot = window.PitmapProfile.draw(profileCanvas, {
      length: profile.line.length, mesh: profile.mesh, points: profile.points, zOffset: zc,
      water: waterZ, trueScale: trueScale && trueScale.checked });
    const ab = (p) => "(" + (p.x + (view.centre ? view.centre[0] : 0)).toFixed(1) + ", " +
                      (p.y + (view.centre ? view.centre[1] : 0)).toFixed(1) + ")";
    profileCaption.textContent = "Profile A " + ab(profile.a) + " \u2192 B " + ab(profile.b) +
      " (ENU m), " + profile.line.length.toFixed(2) + " m: mesh (black line), soundings within " +
      "\u00b1" + corridor() + " m of the plane (orange)" +
      (waterZ !== null ? ", water surface = median track height (blue dashes)" : "") +
      "; vertical exaggeration \u00d7" + profile.plot.exaggeration.toFixed(2) +
      ". Point at the line to read height, depth and slope.";
    profileReadout.textContent = "";
  }
  if (profileCanvas) {
    profileCanvas.addEventListener("mousemove", e => {
      if (!profile || !profile.plot) return;
      const b = profileCanvas.getBoundingClientRect();
      const s = profile.plot.toS(e.clientX - b.left), z = profile.plot.toZ(e.clientY - b.top);
      const near = window.PitmapProfile.nearest(profile.mesh, s, z, profile.plot, 12);
      const zc = view.centre ? view.centre[2] : 0;
      if (!near) {
        profileReadout.textContent = "s " + s.toFixed(2) + " m, z " + (z + zc).toFixed(2) + " m";
        return;
      }
      profileReadout.textContent = "mesh at s " + near.s.toFixed(2) + " m: z " +
        (near.z + zc).toFixed(2) + " m" +
        (waterZ !== null ? ", depth " + (waterZ - near.z).toFixed(2) + " m below the water" : "") +
        ", slope " + near.slopeDeg.toFixed(1) + "\u00b0";
    });
  }
  if (corridorInput) {
    corridorInput.addEventListener("change", () => { if (profile) cutProfile(profile.a, profile.b); });
  }
  if (trueScale) trueScale.addEventListener("change", drawProfile);
  // For scripts and the browser test: the cross-section between two ENU points [x, y] (the
  // vertical plane needs no heights).
  state.crossSection = (a, b) => {
    const c = view.centre || [0, 0, 0];
    clearTool();
    cutProfile(new THREE.Vector3(a[0] - c[0], a[1] - c[1], 0),
                 new THREE.Vector3(b[0] - c[0], b[1] - c[1], 0));
    return state.profile;
  };

  // WebXR: three.js r111's VRButton and renderer.vr (renamed renderer.xr in r112). The scene
  // is in metres, so VR shows the pit at real size; the rig stands at the south edge of the
  // survey, on the water surface (the highest of the track and the surfaces), facing north.
  // WebXR is y-up: the rig is turned so that its y is the scene's z (up) and its -z is north.
  renderer.vr.enabled = true;
  const rig = new THREE.Group();
  rig.rotation.x = Math.PI / 2;
  const vrCamera = new THREE.PerspectiveCamera(50, 1, 0.05, 5000);
  rig.add(vrCamera);
  scene.add(rig);
  function placeRig() {
    const box = new THREE.Box3();
    for (const o of surfaceMeshes().concat(layers.points && layers.points.visible ? [layers.points] : [])) {
      box.expandByObject(o);
    }
    if (box.isEmpty()) box.set(new THREE.Vector3(-1, -1, -1), new THREE.Vector3(1, 1, 1));
    const top = Math.max(box.max.z, waterZ !== null ? waterZ : -Infinity);
    rig.position.set((box.min.x + box.max.x) / 2, box.min.y, top);
  }
  renderer.vr.addEventListener("sessionstart", () => {
    placeRig();
    const session = renderer.vr.getSession();
    if (session) session.updateRenderState({ depthNear: 0.05, depthFar: 50 * view.radius });
    info.textContent = "VR: real size; trigger (select) moves you a tenth of the survey " +
      "where you look";
  });
  // A controller's select (trigger) moves the rig along the gaze, a tenth of the survey.
  renderer.vr.getController(0).addEventListener("select", () => {
    const d = new THREE.Vector3().setFromMatrixColumn(vrCamera.matrixWorld, 2).negate();
    rig.position.addScaledVector(d.normalize(), 0.1 * view.radius);
  });
  const vrButton = THREE.VRButton.createButton(renderer);
  vrButton.id = "viewer3d-vr";
  if (vrButton.tagName === "A") vrButton.removeAttribute("href");  // no link out of the page
  vrButton.title = "WebXR immersive VR at real size (needs a headset and a browser with WebXR)";
  el.appendChild(vrButton);

  // glTF binary (.glb) files: the page's own (pitmap-report --view-gltf) or one opened here.
  // The 12-byte header is checked first (magic "glTF", version 2, length = the file's size),
  // then GLTFLoader reads it; every failure is a message in the page.
  function glbProblem(buffer) {
    const n = buffer.byteLength;
    if (n < 20) return "too short for a glTF binary (" + n + " bytes)";
    const h = new DataView(buffer, 0, 20);
    if (h.getUint32(0, true) !== 0x46546c67) return "not a glTF binary (it does not start with \"glTF\")";
    const version = h.getUint32(4, true);
    if (version !== 2) return "glTF binary version " + version + " (only version 2 is read)";
    const length = h.getUint32(8, true);
    if (length > n) return "truncated: its header says " + length + " bytes, the file has " + n;
    if (length < n) return "its header says " + length + " bytes, the file has " + n;
    if (h.getUint32(16, true) !== 0x4e4f534a || 20 + h.getUint32(12, true) > n) {
      return "no JSON chunk after the header";
    }
    return null;
  }
  let gltfCheckbox = null;
  function gltfFailed(name, why) {
    state.gltf = { name: name, status: "error", message: why, triangles: 0 };
    showProblem("glTF " + name + ": " + why);
    info.textContent = "";
  }
  // Reads a .glb (ArrayBuffer) into the view; the promise resolves with state.gltf once it
  // is shown or refused (a message in the page either way).
  function loadGltf(buffer, name) {
    showProblem("");
    const bad = glbProblem(buffer);
    if (bad) {
      gltfFailed(name, bad);
      requestRender();
      return Promise.resolve(state.gltf);
    }
    state.gltf = { name: name, status: "loading", message: "", triangles: 0 };
    info.textContent = "reading " + name + " ...";
    const why = (e) => (e && e.message ? e.message : String(e));
    return new Promise(resolve => {
      const done = () => {
        requestRender(300);  // parsed asynchronously: no input event follows it
        resolve(state.gltf);
      };
      try {
        new THREE.GLTFLoader().parse(buffer, "", g => {
          try {
            addGltf(g, name);
          } catch (e) {
            gltfFailed(name, "cannot show it: " + why(e));
          }
          done();
        }, e => {
          gltfFailed(name, "cannot read it: " + why(e));
          done();
        });
      } catch (e) {  // GLTFLoader throws some errors (bad JSON) instead of calling back
        gltfFailed(name, "cannot read it: " + why(e));
        done();
      }
    });
  }
  state.openGltf = loadGltf;  // for scripts and the browser test: (ArrayBuffer, name)
  function addGltf(gltf, name) {
    if (!gltf.scene) throw new Error("the file has no scene");
    const root = new THREE.Group();
    root.rotation.x = Math.PI / 2;  // glTF y-up (E, U, -N) back to ENU z-up
    root.add(gltf.scene);
    root.updateMatrixWorld(true);
    const box = new THREE.Box3().setFromObject(root);
    if (box.isEmpty()) throw new Error("the file has no geometry");
    const first = !view.centre;  // a glTF page: frame the view on the file
    if (first) {
      const c = box.getCenter(new THREE.Vector3());
      view.centre = [c.x, c.y, c.z];
      view.zlim = [box.min.z - c.z, box.max.z - c.z];
    }
    root.position.set(-view.centre[0], -view.centre[1], -view.centre[2]);
    root.updateMatrixWorld(true);
    let triangles = 0;
    root.traverse(o => {
      if (!o.isMesh && !o.isPoints) return;
      const g = o.geometry;
      if (!g.attributes.color) {  // no colours of its own: by depth, as the report's mesh
        const a = g.attributes.position, v = new THREE.Vector3();
        const c = new Float32Array(a.count * 3);
        for (let i = 0; i < a.count; ++i) {
          colourOf(v.set(a.getX(i), a.getY(i), a.getZ(i)).applyMatrix4(o.matrixWorld).z, c, 3 * i);
        }
        g.setAttribute("color", new THREE.BufferAttribute(c, 3));
      }
      if (o.isPoints) {
        o.material = new THREE.PointsMaterial({ size: 2, sizeAttenuation: false,
                                                vertexColors: THREE.VertexColors });
        return;
      }
      if (!g.attributes.normal) g.computeVertexNormals();
      o.material = new THREE.MeshLambertMaterial({ vertexColors: THREE.VertexColors,
                                                   side: THREE.DoubleSide });
      triangles += (g.index ? g.index.count : g.attributes.position.count) / 3;
    });
    if (layers.gltf) scene.remove(layers.gltf);
    scene.add(root);
    layers.gltf = root;
    const shown = new THREE.Box3().setFromObject(root);
    if (first || !shown.intersectsBox(extentOfReport())) {
      frameView(shown.getCenter(new THREE.Vector3()), shown.getSize(new THREE.Vector3()).length() / 2);
    }
    if (layers.mesh && layers.mesh.visible) setLayerVisible("mesh", false);  // replaces it
    if (!gltfCheckbox) gltfCheckbox = checkbox("glTF", "gltf");
    gltfCheckbox.lastChild.textContent = " glTF " + name + " ";
    state.gltf = { name: name, status: "loaded", message: "", triangles: triangles };
    info.textContent = "glTF " + name + ": " + triangles + " triangles" +
      (layers.mesh ? " (it replaces the report's mesh; tick \"mesh\" to see both)" : "");
  }
  function extentOfReport() {
    const box = new THREE.Box3();
    for (const key of ["mesh", "points"]) if (layers[key]) box.expandByObject(layers[key]);
    return box;
  }

  // The controls under the view.
  const bar = document.getElementById("viewer3d-bar");
  const checkboxes = {};
  function checkbox(label, key) {
    if (!layers[key]) return null;
    const l = document.createElement("label");
    const c = document.createElement("input");
    c.type = "checkbox";
    c.checked = true;
    c.addEventListener("change", () => { layers[key].visible = c.checked; });
    l.appendChild(c);
    l.appendChild(document.createTextNode(" " + label + " "));
    bar.insertBefore(l, bar.querySelector("button"));
    checkboxes[key] = c;
    return l;
  }
  function setLayerVisible(key, on) {
    layers[key].visible = on;
    if (checkboxes[key]) checkboxes[key].checked = on;
  }
  function button(label, fn) {
    const b = document.createElement("button");
    b.textContent = label;
    b.addEventListener("click", () => fn(b));
    bar.appendChild(b);
    return b;
  }
  checkbox("mesh", "mesh");
  checkbox("soundings", "points");
  checkbox("trajectory after SLAM (white)", "trajectory_after");
  checkbox("trajectory before SLAM (orange)", "trajectory_before");
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
  const toolButtons = {};
  function toolButton(kind, label, stopLabel, prompt) {
    toolButtons[kind] = button(label, b => {
      const on = tool.kind !== kind;
      for (const k in toolButtons) toolButtons[k].textContent = toolButtons[k].dataset.label;
      clearTool();
      tool.kind = on ? kind : null;
      if (on) b.textContent = stopLabel;
      info.textContent = on ? prompt : "";
    });
    toolButtons[kind].dataset.label = label;
  }
  toolButton("distance", "measure distance", "stop measuring", "distance: click the first point");
  toolButton("section", "cross-section", "stop cross-section",
             "cross-section: click the first point (A) on the mesh or the soundings");
  const fileInput = document.createElement("input");
  fileInput.type = "file";
  fileInput.accept = ".glb,model/gltf-binary";
  fileInput.id = "viewer3d-open-gltf";
  fileInput.hidden = true;
  fileInput.addEventListener("change", () => {
    const f = fileInput.files[0];
    if (!f) return;
    f.arrayBuffer().then(buffer => loadGltf(buffer, f.name),
                         e => gltfFailed(f.name, "cannot read the file: " + e));
    fileInput.value = "";
  });
  bar.appendChild(fileInput);
  button("open glTF...", () => fileInput.click()).title =
    "show a local .glb (pitmap's mesh.glb, glTF 2.0 binary) in this view";

  window.addEventListener("resize", () => {
    if (renderer.vr.isPresenting()) return;
    camera.aspect = W() / H();
    camera.updateProjectionMatrix();
    renderer.setSize(W(), H());
    if (profile) drawProfile();
  });
  // The mesh tiles of P/tiles/mesh (data.mesh_tiles), loaded by view (viewer3d_tiles.js).
  const tileView = data.mesh_tiles && window.PitmapTiles && view.centre
    ? window.PitmapTiles.attach({
      scene: scene, camera: camera, canvas: renderer.domElement, centre: view.centre,
      requestRender: requestRender, colourOf: colourOf,
      info: text => { info.textContent = text; }, state: state }, data.mesh_tiles)
    : null;
  // For scripts and the browser test: look from an ENU position at an ENU target (orbit).
  state.setCamera = (position, target) => {
    const c = view.centre || [0, 0, 0];
    camera.position.set(position[0] - c[0], position[1] - c[1], position[2] - c[2]);
    orbit.target.set(target[0] - c[0], target[1] - c[1], target[2] - c[2]);
    orbit.update();
    requestRender(300);
  };
  let last = performance.now();
  renderer.setAnimationLoop(now => {
    if (tileView) tileView.update();
    fpStep(Math.min(0.1, (now - last) / 1000));
    last = now;
    state.ticks += 1;
    const vr = renderer.vr.isPresenting();
    const moving = fp.on && fp.keys.size > 0;
    if (!(vr || moving || renderWanted || now < renderUntil || state.frames < 3)) return;
    renderWanted = false;
    renderer.render(scene, vr ? vrCamera : camera);
    state.frames += 1;
    state.ready = true;
  });

  // Equipment models (pitmap-report --equipment): each .glb placed at its position and heading
  // in the scene beside the mesh, as the paper's VR scene shows the mining vehicle. glTF's
  // front faces +Z, which is south in pitmap's y-up (E, U, -N) convention, so a heading h
  // (clockwise from grid north) turns the model by 180 - h about up. Without a height the
  // model stands on the mesh (the highest surface under its position), else on the water.
  function surfaceZ(x, y) {
    if (layers.mesh) {
      const down = new THREE.Raycaster(new THREE.Vector3(x, y, 1e5), new THREE.Vector3(0, 0, -1));
      const hit = down.intersectObject(layers.mesh);
      if (hit.length) return hit[0].point.z;
    }
    return waterZ !== null ? waterZ : 0;
  }
  function placeEquipment(item) {
    const record = { name: item.name, status: "loading", message: "", centre: null };
    state.equipment.push(record);
    const failed = why => {
      record.status = "error";
      record.message = why;
      showProblem("equipment " + item.name + ": " + why);
      requestRender(300);
    };
    const buffer = bytes(item.glb);
    const bad = glbProblem(buffer);
    if (bad) return failed(bad);
    try {
      new THREE.GLTFLoader().parse(buffer, "", g => {
        if (!g.scene) return failed("the file has no scene");
        const upright = new THREE.Group();
        upright.rotation.x = Math.PI / 2;  // glTF y-up to z-up
        upright.add(g.scene);
        const root = new THREE.Group();
        root.add(upright);
        root.rotation.z = (180 - item.heading_deg) * Math.PI / 180;
        root.updateMatrixWorld(true);
        const box = new THREE.Box3().setFromObject(root);
        if (box.isEmpty()) return failed("the file has no geometry");
        // The model's footprint centre at the position, its lowest point on the ground.
        const c = box.getCenter(new THREE.Vector3());
        const [x, y] = [item.position_m[0] - view.centre[0], item.position_m[1] - view.centre[1]];
        const z = item.position_m[2] === null ? surfaceZ(x, y) : item.position_m[2] - view.centre[2];
        root.position.set(x - c.x, y - c.y, z - box.min.z);
        scene.add(root);
        layers["equipment_" + state.equipment.indexOf(record)] = root;
        root.updateMatrixWorld(true);
        const placed = new THREE.Box3().setFromObject(root).getCenter(new THREE.Vector3());
        record.centre = [placed.x + view.centre[0], placed.y + view.centre[1],
                         placed.z + view.centre[2]];
        record.status = "placed";
        requestRender(300);
      }, e => failed("cannot read it: " + (e && e.message ? e.message : e)));
    } catch (e) {
      failed("cannot read it: " + (e && e.message ? e.message : e));
    }
  }
  for (const item of data.equipment || []) placeEquipment(item);

  if (data.gltf) loadGltf(bytes(data.gltf.glb), data.gltf.name);
})();
