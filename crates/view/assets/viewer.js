// locap view: plays one take from the data embedded in this page (see crates/view/src/page.rs
// for the format). No network: three.js is embedded as text and imported from a blob: URL.
//
// State for tests and scripts: window.locapViewer, and data attributes on <body>
// (data-ready, data-frame, data-spheres, data-visible, data-filled, data-outlier, data-missing,
// data-ghosts, data-joints, data-error-mm, data-load-ms, data-error). URL hash: #frame=N
// (0-based frame index) opens or moves the viewer to frame N; &play=1 starts playback.

const body = document.body;
const $ = (id) => document.getElementById(id);
const meta = JSON.parse($('locap-meta').textContent);
const T = meta.frames;
const M = meta.markers.length;
const Q = meta.quant;
const STATE_COLOURS = ['#7fb2ff', '#3ddc84', '#ffa726', '#ff4d4f'];
const STATE_LABELS = ['captured', 'filled by locap', 'outlier fixed', 'still missing'];
const viewer = (window.locapViewer = {
  ready: false, frame: 0, frames: T, playing: false, playedMs: 0, playedFrames: 0, spheresDrawn: 0, ghostsDrawn: 0, jointsDrawn: 0,
  counts: { visible: 0, filled: 0, outlier: 0, missing: 0 }, errorMm: null, loadMs: null, error: null, meta,
  // Milliseconds since navigation start when each loading step ended.
  timings: { script: Math.round(performance.now()) },
});

function fail(message) {
  viewer.error = message;
  body.dataset.error = message;
  $('message').textContent = message;
  $('message').hidden = false;
}

// ---- data blocks: base64 -> zlib -> typed array ----
async function blockBytes(name) {
  const el = $('locap-block-' + name);
  const text = el.textContent;
  el.textContent = ''; // the decoded copy is all we keep
  let compressed;
  if (typeof Uint8Array.fromBase64 === 'function') {
    compressed = Uint8Array.fromBase64(text);
  } else {
    compressed = new Uint8Array(await (await fetch('data:application/octet-stream;base64,' + text)).arrayBuffer());
  }
  const stream = new Blob([compressed]).stream().pipeThrough(new DecompressionStream('deflate'));
  return new Response(stream).arrayBuffer();
}

async function block(name) {
  const info = meta.blocks.find((b) => b.name === name);
  if (!info) return null;
  const buffer = await blockBytes(name);
  const array = info.dtype === 'i16' ? new Int16Array(buffer) : info.dtype === 'f32' ? new Float32Array(buffer) : new Uint8Array(buffer);
  if (array.length !== info.len) throw new Error(`data block ${name} has ${array.length} values, expected ${info.len}`);
  return array;
}

// Prefix sums per track (delta_order of them) undo the differencing, wrapping like the
// encoder's i16 arithmetic.
function undelta(steps) {
  for (let c = 0; c < steps.length; c += T) {
    for (let order = 0; order < meta.delta_order; order++) {
      let v = 0;
      for (let f = c; f < c + T; f++) {
        v = ((v + steps[f]) << 16) >> 16;
        steps[f] = v;
      }
    }
  }
  return steps;
}

// Position of track k at frame f, metres, in the viewer's axes (Y up).
function point(steps, k, f, out) {
  for (let a = 0; a < 3; a++) out[a] = (Q.offset_mm[a] + (steps[(k * 3 + a) * T + f] + 32767) * Q.step_mm[a]) * 0.001;
  return out;
}

async function main() {
  $('title').textContent = meta.title;
  document.title = `${meta.title} - locap view`;
  const [positions, states, joints, compare, compareStates, errors] = await Promise.all(
    ['positions', 'states', 'joints', 'compare', 'compare_states', 'error'].map(block));
  undelta(positions);
  if (joints) undelta(joints);
  if (compare) undelta(compare);
  viewer.timings.data = Math.round(performance.now());

  const threeSource = $('three-src').textContent;
  $('three-src').textContent = '';
  const THREE = await import(URL.createObjectURL(new Blob([threeSource], { type: 'text/javascript' })));

  viewer.timings.three = Math.round(performance.now());
  const canvas = $('scene');
  let renderer;
  try {
    renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  } catch (e) {
    fail('WebGL is not available in this browser: ' + e.message);
    return;
  }
  renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
  viewer.timings.webgl = Math.round(performance.now());
  const scene = new THREE.Scene();
  scene.background = new THREE.Color('#16181d');
  scene.add(new THREE.HemisphereLight(0xffffff, 0x303040, 2.2));
  const sun = new THREE.DirectionalLight(0xffffff, 1.6);
  sun.position.set(3, 6, 4);
  scene.add(sun);
  const floorY = Math.min(0, Q.offset_mm[1] * 0.001);
  // Floor grid, 20 m in 0.5 m cells, built from one segment per cell edge rather than
  // THREE.GridHelper's 20 m lines: SwiftShader (the software WebGL of headless Chromium)
  // drops a whole line when one end is behind the camera, which left the near floor empty.
  {
    const cell = 0.5, half = 20, v = [];
    for (let i = -half; i <= half; i++) {
      for (let j = -half; j < half; j++) {
        v.push(i * cell, floorY, j * cell, i * cell, floorY, (j + 1) * cell);
        v.push(j * cell, floorY, i * cell, (j + 1) * cell, floorY, i * cell);
      }
    }
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(v), 3));
    scene.add(new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ color: 0x353a45 })));
  }
  const camera = new THREE.PerspectiveCamera(40, 1, 0.05, 200);

  const sphere = new THREE.SphereGeometry(1, 14, 10);
  const instanced = (count, radius, material) => {
    const mesh = new THREE.InstancedMesh(sphere, material, Math.max(count, 1));
    mesh.count = 0;
    mesh.userData.radius = radius;
    mesh.frustumCulled = false;
    scene.add(mesh);
    return mesh;
  };
  const markerMesh = instanced(M, 0.018, new THREE.MeshLambertMaterial({ color: 0xffffff }));
  const ghostMesh = instanced(M, 0.012, new THREE.MeshBasicMaterial({ color: STATE_COLOURS[3], transparent: true, opacity: 0.35, depthWrite: false }));
  const compareMesh = compare ? instanced(M, 0.011, new THREE.MeshBasicMaterial({ color: 0xf5f5f5, wireframe: true })) : null;
  const jointCount = meta.skeleton ? meta.skeleton.joints.length : 0;
  const jointMesh = joints ? instanced(jointCount, 0.012, new THREE.MeshLambertMaterial({ color: 0xe040fb })) : null;
  const lines = (pairs, colour, opacity) => {
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(Math.max(pairs, 1) * 6), 3));
    const l = new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ color: colour, transparent: opacity < 1, opacity }));
    l.frustumCulled = false;
    scene.add(l);
    return l;
  };
  const edgeLines = meta.edges.length ? lines(meta.edges.length, 0x9aa4b5, 0.45) : null;
  const bones = joints ? meta.skeleton.parents.map((p, j) => [p, j]).filter(([p]) => p >= 0) : [];
  const boneLines = joints ? lines(bones.length, 0xe040fb, 1) : null;
  const errorLines = compare ? lines(M, 0xffeb3b, 0.9) : null;

  // ---- options ----
  const options = { edges: meta.edges.length > 0, skeleton: !!joints, compare: !!compare, ghosts: true, follow: true };
  const legend = $('legend');
  legend.innerHTML = STATE_COLOURS.map((c, i) => `<div><span class="dot" style="background:${c}"></span>${STATE_LABELS[i]} <span id="count-${i}"></span></div>`).join('')
    + (joints ? '<div><span class="dot" style="background:#e040fb"></span>skeleton</div>' : '')
    + (compare ? `<div><span class="dot" style="background:none;border:1px solid #f5f5f5"></span>${escapeHtml(meta.compare.title)}</div>` : '')
    + '<hr style="border-color:#3a3f4a">'
    + Object.keys(options).filter((k) => (k !== 'edges' || meta.edges.length) && (k !== 'skeleton' || joints) && (k !== 'compare' || compare))
      .map((k) => `<label><input type="checkbox" data-option="${k}" ${options[k] ? 'checked' : ''}> ${{ edges: 'neighbour edges', skeleton: 'skeleton', compare: 'compare', ghosts: 'missing: last seen', follow: 'follow' }[k]}</label>`).join('');
  legend.addEventListener('change', (e) => {
    const k = e.target.dataset.option;
    if (k) { options[k] = e.target.checked; setFrame(viewer.frame, true); }
  });

  // ---- orbit camera: drag to turn, right/shift-drag to pan, wheel to zoom ----
  const target = new THREE.Vector3();
  const orbit = { radius: 3.4, theta: 0.6, phi: 1.25 };
  const centroid = (f, out) => {
    let n = 0; const p = [0, 0, 0]; out.set(0, 0, 0);
    for (let k = 0; k < M; k++) {
      if (states[k * T + f] === 3) continue;
      point(positions, k, f, p); out.x += p[0]; out.y += p[1]; out.z += p[2]; n++;
    }
    if (n) out.multiplyScalar(1 / n); else out.set((Q.offset_mm[0] + 32767 * Q.step_mm[0]) * 0.001, 1, (Q.offset_mm[2] + 32767 * Q.step_mm[2]) * 0.001);
    return out;
  };
  const placeCamera = () => {
    const s = Math.sin(orbit.phi);
    camera.position.set(target.x + orbit.radius * s * Math.sin(orbit.theta), target.y + orbit.radius * Math.cos(orbit.phi), target.z + orbit.radius * s * Math.cos(orbit.theta));
    camera.lookAt(target);
  };
  let drag = null;
  canvas.addEventListener('pointerdown', (e) => { drag = { x: e.clientX, y: e.clientY, pan: e.button !== 0 || e.shiftKey }; canvas.setPointerCapture(e.pointerId); });
  canvas.addEventListener('pointerup', () => { drag = null; });
  canvas.addEventListener('contextmenu', (e) => e.preventDefault());
  canvas.addEventListener('pointermove', (e) => {
    if (drag) {
      const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
      drag.x = e.clientX; drag.y = e.clientY;
      if (drag.pan) {
        const right = new THREE.Vector3().setFromMatrixColumn(camera.matrix, 0);
        const up = new THREE.Vector3().setFromMatrixColumn(camera.matrix, 1);
        const k = orbit.radius * 0.0015;
        target.addScaledVector(right, -dx * k).addScaledVector(up, dy * k);
        options.follow = false;
        const box = legend.querySelector('[data-option=follow]'); if (box) box.checked = false;
      } else {
        orbit.theta -= dx * 0.006;
        orbit.phi = Math.min(Math.PI - 0.05, Math.max(0.05, orbit.phi - dy * 0.006));
      }
      requestRender();
    } else {
      hover = { x: e.offsetX, y: e.offsetY };
      requestRender();
    }
  });
  canvas.addEventListener('pointerleave', () => { hover = null; $('tip').hidden = true; });
  canvas.addEventListener('wheel', (e) => { e.preventDefault(); orbit.radius = Math.min(100, Math.max(0.3, orbit.radius * Math.exp(e.deltaY * 0.001))); requestRender(); }, { passive: false });

  // ---- hover: names of markers, missing markers and joints ----
  let hover = null;
  const raycaster = new THREE.Raycaster();
  const drawnMarker = new Int32Array(M), drawnGhost = new Int32Array(M);
  const pick = () => {
    if (!hover) return;
    const rect = canvas.getBoundingClientRect();
    raycaster.setFromCamera(new THREE.Vector2((hover.x / rect.width) * 2 - 1, -(hover.y / rect.height) * 2 + 1), camera);
    const targets = [markerMesh, ghostMesh, jointMesh].filter((m) => m && m.visible && m.count > 0);
    const hit = raycaster.intersectObjects(targets, false)[0];
    const tip = $('tip');
    if (!hit) { tip.hidden = true; return; }
    let text;
    if (hit.object === jointMesh) text = `joint ${escapeHtml(meta.skeleton.joints[hit.instanceId])}`;
    else {
      const k = (hit.object === markerMesh ? drawnMarker : drawnGhost)[hit.instanceId];
      const s = states[k * T + viewer.frame];
      text = `${escapeHtml(meta.markers[k])} <span style="color:${STATE_COLOURS[s]}">${STATE_LABELS[s]}</span>`;
      if (compare && compareStates[k * T + viewer.frame] !== 3 && s !== 3) {
        const a = point(positions, k, viewer.frame, [0, 0, 0]), b = point(compare, k, viewer.frame, [0, 0, 0]);
        text += ` &middot; ${(Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]) * 1000).toFixed(1)} mm from ${escapeHtml(meta.compare.title)}`;
      }
    }
    tip.innerHTML = text;
    tip.style.left = hover.x + 14 + 'px';
    tip.style.top = hover.y + 10 + 'px';
    tip.hidden = false;
  };

  // ---- drawing one frame ----
  const matrix = new THREE.Matrix4(), colour = new THREE.Color(), p = [0, 0, 0], q = [0, 0, 0];
  const stateColours = STATE_COLOURS.map((c) => new THREE.Color(c));
  const place = (mesh, i, xyz) => {
    const r = mesh.userData.radius;
    matrix.makeScale(r, r, r).setPosition(xyz[0], xyz[1], xyz[2]);
    mesh.setMatrixAt(i, matrix);
  };
  const followTarget = new THREE.Vector3();
  // A marker never seen has no last position to show.
  const everSeen = Array.from({ length: M }, (_, k) => states.subarray(k * T, (k + 1) * T).some((s) => s !== 3));
  function drawFrame(f) {
    const counts = [0, 0, 0, 0];
    let drawn = 0, ghosts = 0;
    for (let k = 0; k < M; k++) {
      const s = states[k * T + f];
      counts[s]++;
      point(positions, k, f, p);
      if (s === 3) {
        if (options.ghosts && everSeen[k]) { place(ghostMesh, ghosts, p); drawnGhost[ghosts++] = k; }
      } else {
        place(markerMesh, drawn, p);
        markerMesh.setColorAt(drawn, stateColours[s]);
        drawnMarker[drawn++] = k;
      }
    }
    markerMesh.count = drawn; ghostMesh.count = ghosts;
    markerMesh.instanceMatrix.needsUpdate = true; ghostMesh.instanceMatrix.needsUpdate = true;
    if (markerMesh.instanceColor) markerMesh.instanceColor.needsUpdate = true;
    if (edgeLines) {
      edgeLines.visible = options.edges;
      const a = edgeLines.geometry.attributes.position.array;
      meta.edges.forEach(([i, j], e) => {
        const ok = states[i * T + f] !== 3 && states[j * T + f] !== 3;
        point(positions, i, f, p); point(positions, j, f, q);
        a.set(p, e * 6); a.set(ok ? q : p, e * 6 + 3);
      });
      edgeLines.geometry.attributes.position.needsUpdate = true;
    }
    let jointsDrawn = 0;
    if (jointMesh) {
      jointMesh.visible = boneLines.visible = options.skeleton;
      for (let j = 0; j < jointCount; j++) { point(joints, j, f, p); place(jointMesh, j, p); }
      jointMesh.count = jointCount;
      jointMesh.instanceMatrix.needsUpdate = true;
      const a = boneLines.geometry.attributes.position.array;
      bones.forEach(([parent, j], b) => { point(joints, parent, f, p); point(joints, j, f, q); a.set(p, b * 6); a.set(q, b * 6 + 3); });
      boneLines.geometry.attributes.position.needsUpdate = true;
      jointsDrawn = options.skeleton ? jointCount : 0;
    }
    let compared = 0;
    if (compareMesh) {
      compareMesh.visible = errorLines.visible = options.compare;
      const a = errorLines.geometry.attributes.position.array;
      a.fill(0);
      for (let k = 0; k < M; k++) {
        if (compareStates[k * T + f] === 3) continue;
        point(compare, k, f, q);
        place(compareMesh, compared, q);
        if (states[k * T + f] !== 3) { point(positions, k, f, p); a.set(p, compared * 6); a.set(q, compared * 6 + 3); }
        compared++;
      }
      compareMesh.count = compared;
      compareMesh.instanceMatrix.needsUpdate = true;
      errorLines.geometry.attributes.position.needsUpdate = true;
      errorLines.geometry.setDrawRange(0, compared * 2);
    }
    if (options.follow) {
      centroid(f, followTarget);
      target.lerp(followTarget, viewer.ready ? 0.15 : 1);
    }
    placeCamera();
    renderer.render(scene, camera);
    pick();

    viewer.frame = f;
    viewer.spheresDrawn = drawn;
    viewer.ghostsDrawn = ghosts;
    viewer.jointsDrawn = jointsDrawn;
    viewer.counts = { visible: counts[0], filled: counts[1], outlier: counts[2], missing: counts[3] };
    viewer.errorMm = errors && !Number.isNaN(errors[f]) ? errors[f] : null;
    const d = body.dataset;
    d.frame = f; d.spheres = drawn; d.ghosts = ghosts; d.joints = jointsDrawn; d.compared = compared;
    d.visible = counts[0]; d.filled = counts[1]; d.outlier = counts[2]; d.missing = counts[3];
    if (errors) d.errorMm = viewer.errorMm === null ? '' : viewer.errorMm.toFixed(2);
    counts.forEach((n, i) => { const el = $('count-' + i); if (el) el.textContent = n; });
    $('counts').textContent = `${drawn} of ${M} markers drawn`;
    if (errors) $('error').textContent = `${meta.compare.title}: ${viewer.errorMm === null ? 'no common markers' : viewer.errorMm.toFixed(1) + ' mm mean distance'} (take mean ${meta.compare.mean_error_mm === null ? '-' : meta.compare.mean_error_mm.toFixed(1)} mm)`;
    $('time').textContent = `frame ${f + 1}/${T} (C3D ${meta.first_frame + f}) \u00b7 ${(f / meta.rate_hz).toFixed(3)} s \u00b7 ${meta.rate_hz} Hz`;
    $('scrub').value = f;
    document.title = `${meta.title} - frame ${f} - locap view`;
    for (const c of document.querySelectorAll('.cursor')) c.style.left = chartX(f) + 'px';
  }

  // ---- gap chart: one row per marker, worst state per pixel column ----
  const LABEL_W = 96, ROW_H = 11;
  // Gap chart labels without a subject prefix all markers share (`Male:LFWT` -> `LFWT`).
  const prefix = meta.markers[0].includes(':') ? meta.markers[0].slice(0, meta.markers[0].indexOf(':') + 1) : '';
  const shortNames = meta.markers.map((n) => (prefix && meta.markers.every((m) => m.startsWith(prefix)) ? n.slice(prefix.length) : n));
  const gaps = $('gaps');
  let chartWidth = 0;
  const chartX = (f) => LABEL_W + ((f + 0.5) / T) * chartWidth;
  const frameAtX = (x) => Math.max(0, Math.min(T - 1, Math.floor(((x - LABEL_W) / chartWidth) * T)));
  function drawCharts() {
    const width = $('charts').clientWidth;
    chartWidth = Math.max(10, width - LABEL_W - 10);
    const ratio = window.devicePixelRatio || 1;
    const height = M * ROW_H + 4;
    gaps.width = Math.round(width * ratio); gaps.height = Math.round(height * ratio);
    gaps.style.width = width + 'px'; gaps.style.height = height + 'px';
    const g = gaps.getContext('2d');
    g.scale(ratio, ratio);
    g.font = '10px system-ui, sans-serif';
    g.textBaseline = 'middle';
    const columns = Math.max(1, Math.floor(chartWidth));
    for (let k = 0; k < M; k++) {
      g.fillStyle = '#8a919c';
      g.fillText(shortNames[k].slice(0, 15), 4, 2 + k * ROW_H + ROW_H / 2);
      const row = states.subarray(k * T, (k + 1) * T);
      for (let c = 0; c < columns; c++) {
        const f0 = Math.floor((c / columns) * T), f1 = Math.max(f0 + 1, Math.floor(((c + 1) / columns) * T));
        let worst = 0;
        for (let f = f0; f < f1 && worst < 3; f++) if (row[f] > worst) worst = row[f];
        g.fillStyle = worst === 0 ? '#343943' : STATE_COLOURS[worst];
        g.fillRect(LABEL_W + (c / columns) * chartWidth, 2 + k * ROW_H, chartWidth / columns + 0.5, ROW_H - 2);
      }
    }
    if (errors) {
      const ec = $('error-chart'), h = 54;
      $('error-wrap').hidden = false;
      ec.width = Math.round(width * ratio); ec.height = Math.round(h * ratio);
      ec.style.width = width + 'px'; ec.style.height = h + 'px';
      const e = ec.getContext('2d');
      e.scale(ratio, ratio);
      let max = 0;
      for (const v of errors) if (v > max) max = v;
      e.fillStyle = '#8a919c'; e.font = '10px system-ui, sans-serif';
      e.fillText('distance mm', 4, 14); e.fillText(`max ${max.toFixed(1)}`, 4, 28);
      e.strokeStyle = '#ffeb3b'; e.beginPath();
      for (let c = 0; c < columns; c++) {
        const f0 = Math.floor((c / columns) * T), f1 = Math.max(f0 + 1, Math.floor(((c + 1) / columns) * T));
        let v = 0;
        for (let f = f0; f < f1; f++) if (errors[f] > v) v = errors[f];
        const y = h - 4 - (max > 0 ? (v / max) * (h - 10) : 0);
        if (c === 0) e.moveTo(LABEL_W + c, y); else e.lineTo(LABEL_W + (c / columns) * chartWidth, y);
      }
      e.stroke();
    }
  }
  for (const chart of document.querySelectorAll('.chart')) {
    const seek = (e) => { if (e.offsetX >= LABEL_W) { pause(); setFrame(frameAtX(e.offsetX), true); } };
    chart.addEventListener('pointerdown', (e) => { seek(e); chart.setPointerCapture(e.pointerId); });
    chart.addEventListener('pointermove', (e) => {
      if (e.buttons) seek(e);
      const tip = $('tip');
      if (chart.id === 'gaps-wrap' && e.offsetX >= LABEL_W) {
        const k = Math.floor((e.offsetY - 2) / ROW_H), f = frameAtX(e.offsetX);
        if (k >= 0 && k < M) { chart.title = `${meta.markers[k]}, frame ${f}: ${STATE_LABELS[states[k * T + f]]}`; }
      }
      tip.hidden = true;
    });
  }

  // ---- timeline ----
  let renderRequested = false;
  function requestRender() {
    if (renderRequested) return;
    renderRequested = true;
    requestAnimationFrame(tick);
  }
  function setFrame(f, updateHash) {
    f = Math.max(0, Math.min(T - 1, f | 0));
    drawFrame(f);
    if (updateHash && !viewer.playing) history.replaceState(null, '', '#frame=' + f);
  }
  let last = null, carry = 0;
  function tick(now) {
    renderRequested = false;
    if (viewer.playing) {
      if (last !== null) {
        // The playback clock is the animation frames' own: tests read playedMs/playedFrames
        // instead of timing a busy machine from outside.
        viewer.playedMs += now - last;
        carry += ((now - last) / 1000) * meta.rate_hz * Number($('speed').value);
      }
      last = now;
      const step = Math.floor(carry);
      carry -= step;
      viewer.playedFrames += step;
      let f = viewer.frame + step;
      if (f >= T) f = 0;
      drawFrame(f);
      requestRender();
    } else {
      drawFrame(viewer.frame);
    }
  }
  function play() { if (T < 2) return; viewer.playing = true; last = null; carry = 0; viewer.playedMs = 0; viewer.playedFrames = 0; $('play').innerHTML = '&#10074;&#10074;'; requestRender(); }
  function pause() { viewer.playing = false; $('play').innerHTML = '&#9654;'; }
  $('play').addEventListener('click', () => (viewer.playing ? (pause(), setFrame(viewer.frame, true)) : play()));
  $('step-back').addEventListener('click', () => { pause(); setFrame(viewer.frame - 1, true); });
  $('step-fwd').addEventListener('click', () => { pause(); setFrame(viewer.frame + 1, true); });
  $('scrub').max = Math.max(0, T - 1);
  $('scrub').addEventListener('input', (e) => { pause(); setFrame(Number(e.target.value), true); });
  window.addEventListener('keydown', (e) => {
    if (e.target.tagName === 'INPUT' && e.target.type !== 'range' && e.target.type !== 'checkbox') return;
    if (e.key === ' ') { e.preventDefault(); viewer.playing ? (pause(), setFrame(viewer.frame, true)) : play(); }
    else if (e.key === 'ArrowLeft') { e.preventDefault(); pause(); setFrame(viewer.frame - (e.shiftKey ? 10 : 1), true); }
    else if (e.key === 'ArrowRight') { e.preventDefault(); pause(); setFrame(viewer.frame + (e.shiftKey ? 10 : 1), true); }
  });
  const fromHash = () => {
    const h = new URLSearchParams(location.hash.slice(1));
    const num = (k) => (h.has(k) && Number.isFinite(Number(h.get(k))) ? Number(h.get(k)) : null);
    return { frame: num('frame'), play: h.get('play') === '1', theta: num('theta'), phi: num('phi'), radius: num('radius') };
  };
  window.addEventListener('hashchange', () => { const h = fromHash(); if (h.frame !== null && Number.isFinite(h.frame)) { pause(); setFrame(h.frame, false); } });
  viewer.setFrame = (f) => { pause(); setFrame(f, false); return viewer.frame; };
  // Where marker k is drawn at the current frame, in page pixels (null if off screen).
  viewer.screenPosition = (k) => {
    const v = new THREE.Vector3(...point(positions, k, viewer.frame, [0, 0, 0])).project(camera);
    if (Math.abs(v.x) > 1 || Math.abs(v.y) > 1 || v.z > 1) return null;
    const rect = canvas.getBoundingClientRect();
    return { x: rect.left + ((v.x + 1) / 2) * rect.width, y: rect.top + ((1 - v.y) / 2) * rect.height };
  };
  viewer.play = play;
  viewer.pause = pause;

  const resize = () => {
    // Charts first: their height decides how much room the 3D view has.
    drawCharts();
    const rect = $('view').getBoundingClientRect();
    renderer.setSize(rect.width, rect.height, false);
    camera.aspect = rect.width / Math.max(1, rect.height);
    camera.updateProjectionMatrix();
    setFrame(viewer.frame, false);
  };
  window.addEventListener('resize', resize);

  const start = fromHash();
  viewer.frame = Math.max(0, Math.min(T - 1, Number.isFinite(start.frame) && start.frame !== null ? start.frame | 0 : 0));
  centroid(viewer.frame, target);
  // Stand back far enough to see the whole performance area of the first frame.
  if (start.theta !== null) orbit.theta = start.theta;
  if (start.phi !== null) orbit.phi = Math.min(Math.PI - 0.05, Math.max(0.05, start.phi));
  if (start.radius !== null) orbit.radius = Math.min(100, Math.max(0.3, start.radius));
  $('message').hidden = true;
  resize();
  viewer.ready = true;
  viewer.loadMs = Math.round(performance.now());
  body.dataset.loadMs = viewer.loadMs;
  body.dataset.ready = '1';
  if (start.play) play();
}

function escapeHtml(s) {
  return String(s).replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' })[c]);
}

if (T === 0 || M === 0) {
  fail(T === 0 ? 'this take has no frames' : 'this take has no markers');
  body.dataset.ready = '1';
} else {
  main().catch((e) => fail('cannot show this take: ' + (e && e.message ? e.message : e)));
}
