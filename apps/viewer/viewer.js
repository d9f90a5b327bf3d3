/*
 * ICE report viewer: the meshes of a report page with per-vertex fields and the coarse edges of
 * each coarsening method, in one view or two linked side-by-side views.
 *
 * Loaded as a classic script after three's CommonJS build (global THREE): a page opened from disk
 * can load neither ES modules nor files through fetch(). Each data script of the page calls
 * ICE_VIEWER.register(mesh); the page then calls ICE_VIEWER.start(element). A mesh object:
 *   name, input_vertices, input_faces,
 *   display: {vertices, faces, decimated, positions (3 floats a vertex), indices (3 uint32 a face),
 *             points (a point cloud: its vertices drawn as points of point_size, the faces not)},
 *   fields: [{name, problem, kind: "solution"|"error"|"label", method (null: common to all),
 *             values (1 float a vertex), min, max}],
 *   methods: [{name, status: "ok"|"failed", message, coarse_vertices,
 *              edges (6 floats a segment), segments, errors: {problem: relative error}}]
 * with the arrays as base64 of little-endian Float32/Uint32 data.
 *
 * window.iceViewer is the hook for tests: ready, errors, setMesh, setMethod, setOther, setField,
 * setEdges, setSideBySide, state().
 */
(function () {
  'use strict';

  // Collected from the moment this script runs, so that failing data scripts count as well.
  const api = { ready: false, errors: [] };
  window.iceViewer = api;

  // matplotlib's viridis sampled at 17 evenly spaced points (sRGB). Linear interpolation between
  // them stays within 6/255 of the full map.
  const VIRIDIS = ['#440154', '#48186a', '#472d7b', '#424086', '#3b528b', '#33638d', '#2c728e',
    '#26828e', '#21918c', '#1fa088', '#28ae80', '#3fbc73', '#5ec962', '#84d44b', '#addc30',
    '#d8e219', '#fde725'];
  const EDGE_COLOR = '#ff2020';   // a red: in neither viridis nor the label colours
  const BACKGROUND = '#f4f5f7';   // also in viewer.css (.ice-viewport)
  const NO_FIELD_COLOR = '#c4c6ca';
  const FOV = 35;                  // vertical field of view, degrees

  const meshes = [];               // registered mesh objects, in registration order
  let ui = null;                   // DOM and three.js objects, made by start()

  function recordError(message) {
    api.errors.push(message);
    if (ui) showErrors();
  }

  window.addEventListener('error', (event) => {
    // Capturing listener: also sees scripts, styles and images that failed to load (no bubbling).
    const target = event.target;
    if (target && target !== window && (target.src || target.href)) {
      recordError('failed to load ' + (target.src || target.href));
    } else if (event.message === 'Script error.') {
      // Errors of other files are muted for pages opened from disk: the console has the details.
      recordError('a script failed (see the browser console)');
    } else {
      recordError(event.message || String(event.error));
    }
  }, true);
  window.addEventListener('unhandledrejection', (event) => {
    const reason = event.reason;
    recordError('unhandled rejection: ' + (reason && reason.message ? reason.message : String(reason)));
  });

  // ---------------------------------------------------------------------------------------------
  // Data decoding (once per array; results are cached on the registered objects).

  function decodeBase64(text) {
    const binary = atob(text);
    const bytes = new Uint8Array(binary.length);
    for (let i = 0; i < binary.length; i++) bytes[i] = binary.charCodeAt(i);
    return bytes.buffer;
  }

  function typedArray(Type, text, count, what) {
    const buffer = text ? decodeBase64(text) : new ArrayBuffer(0);
    if (buffer.byteLength !== count * 4) {
      throw new Error(`${what}: ${buffer.byteLength} bytes for ${count} values`);
    }
    return new Type(buffer);
  }

  function fieldValues(field, vertexCount) {
    if (!field.decoded) {
      const values = typedArray(Float32Array, field.values, vertexCount, `field "${field.name}"`);
      let min = field.min, max = field.max;
      if (!Number.isFinite(min) || !Number.isFinite(max)) {
        // The writer emits null for a range it could not compute (JSON has no NaN).
        min = Infinity; max = -Infinity;
        for (const v of values) if (Number.isFinite(v)) { if (v < min) min = v; if (v > max) max = v; }
      }
      field.decoded = { values, min, max };
    }
    return field.decoded;
  }

  function edgeSegments(method) {
    if (!method.decodedEdges) {
      method.decodedEdges = typedArray(Float32Array, method.edges, 6 * method.segments,
        `edges of ${method.name}`);
    }
    return method.decodedEdges;
  }

  // ---------------------------------------------------------------------------------------------
  // Colours. The colour attribute holds linear RGB: three.js shades in linear space and converts
  // to sRGB on output, so sRGB colours are converted on the way in.

  const viridisLinear = (function () {
    const keys = VIRIDIS.map((hex) => [1, 3, 5].map((i) => parseInt(hex.substr(i, 2), 16) / 255));
    const lut = new Float32Array(256 * 3);
    const color = new THREE.Color();
    for (let i = 0; i < 256; i++) {
      const x = (i / 255) * (keys.length - 1);
      const k = Math.min(Math.floor(x), keys.length - 2), f = x - k;
      const rgb = [0, 1, 2].map((c) => keys[k][c] * (1 - f) + keys[k + 1][c] * f);
      color.setRGB(rgb[0], rgb[1], rgb[2], THREE.SRGBColorSpace);
      lut.set([color.r, color.g, color.b], 3 * i);
    }
    return lut;
  })();

  // Categorical colour of an integer label: a hash spreads neighbouring labels over the hues,
  // leaving out the reds of the edge lines.
  function labelColor(label, color) {
    let h = Math.imul(label ^ 0x9e3779b9, 0x85ebca6b);
    h ^= h >>> 13;
    h = Math.imul(h, 0xc2b2ae35);
    h = (h ^ (h >>> 16)) >>> 0;
    const hue = 0.07 + 0.86 * ((h & 0xffff) / 0xffff);
    const lightness = [0.42, 0.56, 0.70][(h >>> 16) % 3];
    return color.setHSL(hue, 0.65, lightness, THREE.SRGBColorSpace);
  }

  // Fills `out` (3 floats per vertex). range: [lo, hi] for scalar fields, null for labels.
  function colorVertices(out, values, range) {
    const n = out.length / 3;
    const grey = new THREE.Color(NO_FIELD_COLOR);
    if (!values) {
      for (let i = 0; i < n; i++) out.set([grey.r, grey.g, grey.b], 3 * i);
      return;
    }
    if (!range) {
      const cache = new Map();
      const color = new THREE.Color();
      for (let i = 0; i < n; i++) {
        const label = Math.round(values[i]);
        let rgb = cache.get(label);
        if (!rgb) {
          labelColor(label, color);
          rgb = [color.r, color.g, color.b];
          cache.set(label, rgb);
        }
        out.set(rgb, 3 * i);
      }
      return;
    }
    const [lo, hi] = range;
    const scale = hi > lo ? 255 / (hi - lo) : 0;
    for (let i = 0; i < n; i++) {
      const v = values[i];
      if (!Number.isFinite(v)) {  // NaN, or +inf: a distance on a component no source reaches
        out[3 * i] = grey.r; out[3 * i + 1] = grey.g; out[3 * i + 2] = grey.b;
        continue;
      }
      const k = 3 * (scale ? Math.min(255, Math.max(0, Math.round((v - lo) * scale))) : 128);
      out[3 * i] = viridisLinear[k]; out[3 * i + 1] = viridisLinear[k + 1]; out[3 * i + 2] = viridisLinear[k + 2];
    }
  }

  // ---------------------------------------------------------------------------------------------
  // Registration and queries on the data.

  function register(obj) {
    try {
      if (!obj || typeof obj.name !== 'string' || !obj.display || !Array.isArray(obj.methods)) {
        throw new Error('ICE_VIEWER.register: not a mesh object');
      }
      obj.fields = obj.fields || [];
      meshes.push(obj);
    } catch (e) {
      recordError(e.message);
    }
  }

  function currentMesh() { return meshes[ui.state.mesh]; }
  function findMethod(name) { return currentMesh().methods.find((m) => m.name === name) || null; }
  function methodOk(method) { return method && method.status === 'ok'; }

  // The fields offered for a method: its own and the common ones (method null).
  function fieldsFor(methodName) {
    return currentMesh().fields.filter((f) => f.method === null || f.method === methodName);
  }

  // The field of `methodName` that shows the same thing as `field` (same problem and kind).
  function counterpart(field, methodName) {
    if (!field || field.method === null) return field;
    return currentMesh().fields.find((f) => f.method === methodName && f.kind === field.kind &&
      f.problem === field.problem) || null;
  }

  function formatNumber(v) {
    if (!Number.isFinite(v)) return '—';
    return String(Number(v.toPrecision(3)));
  }

  function formatCount(n) { return Number(n).toLocaleString('en-US'); }

  // ---------------------------------------------------------------------------------------------
  // DOM helpers.

  function element(tag, className, parent) {
    const e = document.createElement(tag);
    if (className) e.className = className;
    if (parent) parent.appendChild(e);
    return e;
  }

  function labelled(text, control, parent) {
    const label = element('label', 'ice-control', parent);
    if (control.type === 'checkbox') {
      label.append(control, ' ' + text);
    } else {
      label.append(text + ' ', control);
    }
    return label;
  }

  function fillSelect(select, items) {
    select.replaceChildren(...items.map(([text, value]) => new Option(text, value)));
  }

  // ---------------------------------------------------------------------------------------------
  // Start: builds the viewport, the scene and the toolbar.

  // Runs fn, reporting an exception in the page: thrown from here it would reach window.onerror
  // muted ("Script error.") on a page opened from disk.
  function reporting(fn) {
    return (...args) => {
      try {
        fn(...args);
      } catch (e) {
        console.error(e);
        recordError(e.message);
      }
    };
  }

  function start(container) {
    try {
      startViewer(container);
    } catch (e) {
      console.error(e);
      recordError(e.message);
      // A half-built view would mislead: only the errors and a message stay.
      ui.viewport.replaceChildren(ui.errorBox);
      container.replaceChildren(ui.viewport);
      showMessage('The 3D view could not be shown.');
    }
  }

  function startViewer(container) {
    const viewport = element('div', 'ice-viewport', container);
    ui = {
      viewport,
      errorBox: element('div', 'ice-errors', viewport),
      state: { mesh: 0, method: null, other: null, field: null, edges: true, sideBySide: false },
    };
    showErrors();
    if (meshes.length === 0) {
      showMessage('No mesh data was loaded.');
      return;
    }
    try {
      ui.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    } catch (e) {
      recordError('WebGL is not available: ' + e.message);
      showMessage('This browser cannot show the 3D view (WebGL is not available).');
      return;
    }
    ui.renderer.setPixelRatio(window.devicePixelRatio);
    ui.renderer.setClearColor(BACKGROUND);
    viewport.prepend(ui.renderer.domElement);
    buildScene();
    ui.legend = element('div', 'ice-legend', viewport);
    const meshInfo = element('div', 'ice-mesh-info', viewport);
    ui.meshSize = element('div', '', meshInfo);
    element('div', 'ice-hint', meshInfo).textContent =
      'drag: rotate · wheel: zoom · right or shift drag: pan · double-click: reset';
    ui.panes = [makePane(), makePane()];
    buildToolbar(container);
    attachOrbitControls();
    selectMesh(0);
    new ResizeObserver(() => render()).observe(viewport);
  }

  function buildToolbar(container) {
    const toolbar = element('div', 'ice-toolbar');
    container.prepend(toolbar);
    const controls = {
      mesh: element('select'), method: element('select'), other: element('select'),
      field: element('select'), sideBySide: element('input'), edges: element('input'),
    };
    controls.sideBySide.type = 'checkbox';
    controls.edges.type = 'checkbox';
    labelled('Mesh', controls.mesh, toolbar).hidden = meshes.length < 2;
    labelled('Method', controls.method, toolbar);
    labelled('side by side', controls.sideBySide, toolbar);
    ui.otherControl = labelled('with', controls.other, toolbar);
    labelled('Field', controls.field, toolbar);
    labelled('coarse edges', controls.edges, toolbar);
    fillSelect(controls.mesh, meshes.map((m, i) => [m.name, String(i)]));
    const on = (control, action) => control.addEventListener('change', reporting(action));
    on(controls.mesh, () => selectMesh(Number(controls.mesh.value)));
    on(controls.method, () => setMethod(controls.method.value));
    on(controls.other, () => setOther(controls.other.value));
    on(controls.field, () => setField(controls.field.value));
    on(controls.sideBySide, () => setSideBySide(controls.sideBySide.checked));
    on(controls.edges, () => setEdges(controls.edges.checked));
    ui.controls = controls;
  }

  function showMessage(text) {
    element('div', 'ice-message', ui.viewport).textContent = text;
    api.ready = true;
  }

  function showErrors() {
    ui.errorBox.hidden = api.errors.length === 0;
    ui.errorBox.textContent = api.errors.length ? 'Errors: ' + api.errors.join('; ') : '';
  }

  function buildScene() {
    const scene = new THREE.Scene();
    const camera = new THREE.PerspectiveCamera(FOV, 1, 0.01, 100);
    scene.add(camera);
    // Lambert divides by pi: intensities are fractions of pi, so that a surface facing the light
    // shows about its own colour and one seen edge-on keeps the ambient part.
    scene.add(new THREE.AmbientLight(0xffffff, 0.45 * Math.PI));
    const light = new THREE.DirectionalLight(0xffffff, 0.6 * Math.PI);
    light.position.set(0.4, 0.6, 0);          // in camera space: from the upper right of the viewer
    light.target.position.set(0, 0, -1);
    camera.add(light, light.target);
    ui.scene = scene;
    ui.camera = camera;
    ui.surfaceMaterial = new THREE.MeshLambertMaterial({
      vertexColors: true, side: THREE.DoubleSide,
      // Pushes the surface back in depth so that edge lines lying on it win the depth test.
      polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1,
    });
    ui.lineMaterial = new THREE.LineBasicMaterial({ color: EDGE_COLOR });
  }

  // A point cloud's points: unlit (its faces are inconsistently oriented, so normals would shade them
  // dark at random), sized in model units like splats so that they close up at any zoom.
  function pointsMaterial(size) {
    return new THREE.PointsMaterial({ vertexColors: true, size, sizeAttenuation: true });
  }

  // A pane is one viewport: the surface and edges of one method, and its overlays.
  function makePane() {
    const el = element('div', 'ice-pane', ui.viewport);
    const pane = {
      el,
      info: element('div', 'ice-pane-info', el),
      overlay: element('div', 'ice-overlay', el),
      group: new THREE.Group(),
      surface: new THREE.Mesh(new THREE.BufferGeometry(), ui.surfaceMaterial),
      points: new THREE.Points(new THREE.BufferGeometry(), pointsMaterial(1)),
      lines: new THREE.LineSegments(new THREE.BufferGeometry(), ui.lineMaterial),
      colorKey: null,
    };
    pane.points.visible = false;
    pane.group.add(pane.surface, pane.points, pane.lines);
    ui.scene.add(pane.group);
    return pane;
  }

  // ---------------------------------------------------------------------------------------------
  // Mesh, method and field selection.

  function prepareMesh(mesh) {
    if (!mesh.prepared) {
      const d = mesh.display;
      const positions = typedArray(Float32Array, d.positions, 3 * d.vertices, `positions of ${mesh.name}`);
      const indices = typedArray(Uint32Array, d.indices, 3 * d.faces, `faces of ${mesh.name}`);
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute('position', new THREE.BufferAttribute(positions, 3));
      geometry.setIndex(new THREE.BufferAttribute(indices, 1));
      geometry.computeVertexNormals();
      geometry.computeBoundingSphere();
      geometry.computeBoundingBox();
      mesh.prepared = {
        position: geometry.getAttribute('position'),
        normal: geometry.getAttribute('normal'),
        index: geometry.getIndex(),
        sphere: geometry.boundingSphere,
        box: geometry.boundingBox,
      };
    }
    return mesh.prepared;
  }

  function selectMesh(index) {
    const previousMethod = ui.state.method;
    ui.state.mesh = index;
    ui.controls.mesh.value = String(index);
    const mesh = currentMesh();
    const prepared = prepareMesh(mesh);
    for (const pane of ui.panes) {
      pane.surface.geometry.dispose();
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute('position', prepared.position);
      geometry.setAttribute('normal', prepared.normal);
      geometry.setIndex(prepared.index);
      geometry.setAttribute('color', new THREE.BufferAttribute(new Float32Array(3 * mesh.display.vertices), 3));
      geometry.boundingSphere = prepared.sphere;
      pane.surface.geometry = geometry;
      // The points share the surface's positions and colours (one colour update serves both).
      pane.points.geometry.dispose();
      const points = new THREE.BufferGeometry();
      points.setAttribute('position', prepared.position);
      points.setAttribute('color', geometry.getAttribute('color'));
      points.boundingSphere = prepared.sphere;
      pane.points.geometry = points;
      // three.js draws a point `size` pixels per (half the viewport's height / depth), where a length L
      // spans L / tan(FOV/2) of them: the points' diameter in model units is point_size.
      pane.points.material.size = (mesh.display.point_size || 1) / Math.tan(THREE.MathUtils.degToRad(FOV) / 2);
      pane.points.visible = !!mesh.display.points;
      pane.surface.visible = !mesh.display.points;
      pane.colorKey = null;
    }
    for (const m of meshes) {
      if (m !== mesh && m.edgeGeometries) {
        for (const g of m.edgeGeometries.values()) g.dispose();
        m.edgeGeometries = null;
      }
    }
    mesh.edgeGeometries = mesh.edgeGeometries || new Map();

    const names = mesh.methods.map((m) => m.name);
    const methodLabels = mesh.methods.map((m) => [methodOk(m) ? m.name : `${m.name} (failed)`, m.name]);
    fillSelect(ui.controls.method, methodLabels);
    fillSelect(ui.controls.other, methodLabels);
    ui.controls.sideBySide.disabled = names.length < 2;
    if (names.length < 2) ui.state.sideBySide = false;
    const firstOk = mesh.methods.find(methodOk);
    ui.state.method = names.includes(previousMethod) ? previousMethod
      : (firstOk ? firstOk.name : names[0] || null);
    chooseOther();
    refreshFields(ui.state.field && counterpartByName(ui.state.field));
    updateMeshInfo();
    resetView();
    update();
  }

  // After a mesh change the selected field name may not exist; its counterpart by kind is kept.
  function counterpartByName(name) {
    const old = meshes.flatMap((m) => m.fields).find((f) => f.name === name);
    return old ? currentMesh().fields.find((f) => f.kind === old.kind && f.problem === old.problem &&
      (f.method === null || f.method === ui.state.method)) || null : null;
  }

  function chooseOther() {
    const names = currentMesh().methods.map((m) => m.name);
    if (!names.includes(ui.state.other) || ui.state.other === ui.state.method) {
      // The last other method: in a report ICE first, QEM last (its strongest configuration, qem_idt).
      ui.state.other = [...names].reverse().find((n) => n !== ui.state.method) || null;
    }
  }

  // Refills the field list for the current method and selects `preferred`, else the first error field
  // (what a person judging a coarsening looks at first), else the first field.
  function refreshFields(preferred) {
    const fields = fieldsFor(ui.state.method);
    fillSelect(ui.controls.field, fields.map((f) => [f.name, f.name]));
    const keep = preferred && fields.includes(preferred) ? preferred : fields.find((f) => f.kind === 'error') || fields[0];
    ui.state.field = keep ? keep.name : null;
    ui.controls.field.disabled = fields.length === 0;
  }

  function setMesh(name) {
    const index = meshes.findIndex((m) => m.name === name);
    if (index < 0) throw new Error(`no mesh "${name}"`);
    selectMesh(index);
    return api.state();
  }

  function setMethod(name) {
    if (!findMethod(name)) throw new Error(`no method "${name}"`);
    const field = currentMesh().fields.find((f) => f.name === ui.state.field);
    ui.state.method = name;
    chooseOther();
    refreshFields(counterpart(field, name));
    update();
    return api.state();
  }

  function setOther(name) {
    if (!findMethod(name)) throw new Error(`no method "${name}"`);
    ui.state.other = name;
    update();
    return api.state();
  }

  function setField(name) {
    if (!fieldsFor(ui.state.method).some((f) => f.name === name)) {
      throw new Error(`no field "${name}" for method ${ui.state.method}`);
    }
    ui.state.field = name;
    update();
    return api.state();
  }

  function setEdges(on) {
    ui.state.edges = Boolean(on);
    update();
    return api.state();
  }

  function setSideBySide(on) {
    ui.state.sideBySide = Boolean(on) && currentMesh().methods.length > 1;
    // The pane's aspect ratio changes: fit the mesh again, keeping the direction of view.
    ui.view.radius = fitView();
    update();
    return api.state();
  }

  // Applies the state to the controls, the panes and the legend, then renders.
  function update() {
    const s = ui.state;
    const c = ui.controls;
    c.method.value = s.method || '';
    c.other.value = s.other || '';
    c.field.value = s.field || '';
    c.sideBySide.checked = s.sideBySide;
    c.edges.checked = s.edges;
    ui.otherControl.hidden = !s.sideBySide;
    ui.viewport.classList.toggle('ice-split', s.sideBySide);

    const mesh = currentMesh();
    const main = mesh.fields.find((f) => f.name === s.field) || null;
    const shown = [{ method: findMethod(s.method), field: main }];
    if (s.sideBySide) shown.push({ method: findMethod(s.other), field: counterpart(main, s.other) });
    for (const entry of shown) {
      // A failed method has no fields of its own: it shows the common ones or a plain surface.
      if (!methodOk(entry.method) && entry.field && entry.field.method !== null) entry.field = null;
      entry.data = entry.field ? fieldValues(entry.field, mesh.display.vertices) : null;
    }
    const range = sharedRange(shown);
    ui.panes.forEach((pane, i) => {
      pane.el.hidden = i >= shown.length;
      if (i < shown.length) updatePane(pane, shown[i], range);
    });
    updateLegend(shown, range);
    render();
  }

  // Scalar fields shown side by side share one colour range so that colours compare; error
  // fields start at 0. null for labels.
  function sharedRange(shown) {
    const withData = shown.filter((e) => e.data);
    if (withData.length === 0 || withData[0].field.kind === 'label') return null;
    let lo = Math.min(...withData.map((e) => e.data.min));
    const hi = Math.max(...withData.map((e) => e.data.max));
    if (withData.some((e) => e.field.kind === 'error')) lo = 0;
    return [lo, hi];
  }

  function updatePane(pane, entry, range) {
    const { method, field, data } = entry;
    const key = (field ? field.name : '') + '|' + (range ? range.join() : '');
    if (pane.colorKey !== key) {
      const colors = pane.surface.geometry.getAttribute('color');
      colorVertices(colors.array, data && data.values, field && field.kind !== 'label' ? range : null);
      colors.needsUpdate = true;
      pane.colorKey = key;
    }

    const ok = methodOk(method);
    pane.lines.visible = ui.state.edges && ok && method.segments > 0;
    if (pane.lines.visible) pane.lines.geometry = edgeGeometry(method);

    pane.overlay.hidden = ok || !method;
    pane.overlay.textContent = method && !ok
      ? `${method.name} failed on this mesh: ${method.message || '(no message)'}` : '';

    const lines = [];
    if (!method) {
      lines.push('no method');
    } else if (ok) {
      lines.push(`${method.name}: ${formatCount(method.coarse_vertices)} coarse vertices, ` +
        `${formatCount(method.segments)} edge segments`);
      const errors = Object.entries(method.errors || {});
      if (errors.length) {
        lines.push('relative error: ' + errors.map(([problem, e]) =>
          `${problem} ${Number.isFinite(e) ? formatNumber(100 * e) + ' %' : '—'}`).join(', '));
      }
      if (ui.state.field && !field) lines.push(`no field like "${ui.state.field}" for ${method.name}`);
    } else {
      lines.push(`${method.name}: failed`);
    }
    pane.info.replaceChildren(...lines.map((t) => { const d = element('div'); d.textContent = t; return d; }));
  }

  function edgeGeometry(method) {
    const cache = currentMesh().edgeGeometries;
    let geometry = cache.get(method.name);
    if (!geometry) {
      geometry = new THREE.BufferGeometry();
      geometry.setAttribute('position', new THREE.BufferAttribute(edgeSegments(method), 3));
      cache.set(method.name, geometry);
    }
    return geometry;
  }

  function updateLegend(shown, range) {
    const legend = ui.legend;
    legend.replaceChildren();
    const fields = shown.map((e) => e.field).filter(Boolean);
    if (fields.length === 0) {
      legend.hidden = true;
      return;
    }
    legend.hidden = false;
    const names = [...new Set(fields.map((f) => f.name))];
    element('div', 'ice-legend-title', legend).textContent = names.join('  |  ');
    if (!range) {
      const data = shown.find((e) => e.data).data;
      element('div', 'ice-legend-note', legend).textContent =
        `categorical colours, labels ${formatCount(data.min)}–${formatCount(data.max)}`;
      return;
    }
    const bar = element('div', 'ice-colorbar', legend);
    bar.style.background = `linear-gradient(to right, ${VIRIDIS.join(', ')})`;
    const labels = element('div', 'ice-colorbar-labels', legend);
    element('span', '', labels).textContent = formatNumber(range[0]);
    element('span', '', labels).textContent = formatNumber(range[1]);
  }

  function updateMeshInfo() {
    const mesh = currentMesh();
    const d = mesh.display;
    const size = d.points ? `${formatCount(d.vertices)} points`
      : `${formatCount(d.vertices)} vertices, ${formatCount(d.faces)} faces`;
    ui.meshSize.textContent = d.decimated
      ? `${mesh.name}: decimated display mesh, ${size} (input ${formatCount(mesh.input_vertices)} ` +
        `vertices, ${formatCount(mesh.input_faces)} faces)`
      : `${mesh.name}: ${size}`;
  }

  // ---------------------------------------------------------------------------------------------
  // Camera: orbit around the mesh centre, one camera for both panes (linked views).

  function fitDistance() {
    const { width, height } = paneSize();
    const vertical = THREE.MathUtils.degToRad(FOV) / 2;
    const horizontal = Math.atan(Math.tan(vertical) * width / height);
    return 1.1 * ui.view.size / Math.sin(Math.min(vertical, horizontal));
  }

  // The distance at which every vertex fits the pane, seen from the view's direction: tighter than
  // the bounding sphere (or box) for long meshes, which those leave small. One pass over the display
  // vertices (at most a few hundred thousand).
  function fitVertices(position) {
    const { width, height } = paneSize();
    const tanVertical = Math.tan(THREE.MathUtils.degToRad(FOV) / 2);
    const tanHorizontal = tanVertical * width / height;
    const view = ui.view;
    const back = new THREE.Vector3().setFromSphericalCoords(1, view.phi, view.theta);  // target -> camera
    const right = new THREE.Vector3().crossVectors(new THREE.Vector3(0, 1, 0), back).normalize();
    const up = new THREE.Vector3().crossVectors(back, right);
    const p = position.array, t = view.target;
    let distance = 0;
    for (let i = 0; i < p.length; i += 3) {
      const x = p[i] - t.x, y = p[i + 1] - t.y, z = p[i + 2] - t.z;
      const depth = x * back.x + y * back.y + z * back.z;
      const across = Math.abs(x * right.x + y * right.y + z * right.z);
      const along = Math.abs(x * up.x + y * up.y + z * up.z);
      distance = Math.max(distance, depth + across / tanHorizontal, depth + along / tanVertical);
    }
    return 1.08 * distance;
  }

  function resetView() {
    const prepared = prepareMesh(currentMesh());
    const sphere = prepared.sphere;
    const centre = prepared.box.getCenter(new THREE.Vector3());
    ui.view = { target: centre, size: sphere.radius || 1, theta: 0.6, phi: 1.15, radius: 1 };
    ui.view.radius = fitView();
  }

  // The camera distance that fits the current mesh from the current direction (the vertices; the
  // bounding sphere if they give nothing usable).
  function fitView() {
    const fitted = fitVertices(prepareMesh(currentMesh()).position);
    return fitted > 0 && Number.isFinite(fitted) ? fitted : fitDistance();
  }

  function placeCamera() {
    const { view, camera } = ui;
    camera.position.setFromSphericalCoords(view.radius, view.phi, view.theta).add(view.target);
    camera.lookAt(view.target);
    // Depth range around the mesh's bounding sphere, wherever panning moved the target.
    const centre = prepareMesh(currentMesh()).sphere.center;
    const distance = camera.position.distanceTo(centre);
    camera.near = Math.max(distance - 1.2 * view.size, 0.01 * distance, 1e-4 * view.size);
    camera.far = distance + 1.2 * view.size;
  }

  function attachOrbitControls() {
    const viewport = ui.viewport;
    let drag = null;
    viewport.addEventListener('contextmenu', (e) => e.preventDefault());
    viewport.addEventListener('pointerdown', (e) => {
      drag = { x: e.clientX, y: e.clientY, pan: e.button !== 0 || e.shiftKey };
      viewport.setPointerCapture(e.pointerId);
    });
    viewport.addEventListener('pointermove', (e) => {
      if (!drag) return;
      const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
      drag.x = e.clientX;
      drag.y = e.clientY;
      const view = ui.view;
      const height = paneSize().height;
      if (drag.pan) {
        // World units per pixel at the target's depth.
        const scale = 2 * view.radius * Math.tan(THREE.MathUtils.degToRad(FOV) / 2) / height;
        const right = new THREE.Vector3().setFromMatrixColumn(ui.camera.matrix, 0);
        const up = new THREE.Vector3().setFromMatrixColumn(ui.camera.matrix, 1);
        view.target.addScaledVector(right, -dx * scale).addScaledVector(up, dy * scale);
      } else {
        view.theta -= 2 * Math.PI * dx / height;
        view.phi = THREE.MathUtils.clamp(view.phi - 2 * Math.PI * dy / height, 0.01, Math.PI - 0.01);
      }
      requestRender();
    });
    const endDrag = () => { drag = null; };
    viewport.addEventListener('pointerup', endDrag);
    viewport.addEventListener('pointercancel', endDrag);
    viewport.addEventListener('wheel', (e) => {
      e.preventDefault();
      const pixels = e.deltaMode === WheelEvent.DOM_DELTA_LINE ? 16 * e.deltaY : e.deltaY;
      const view = ui.view;
      view.radius = THREE.MathUtils.clamp(view.radius * Math.exp(pixels * 0.0015), 0.02 * view.size, 50 * view.size);
      requestRender();
    }, { passive: false });
    viewport.addEventListener('dblclick', () => {
      resetView();
      requestRender();
    });
  }

  // ---------------------------------------------------------------------------------------------
  // Rendering: on demand, one scissored viewport per pane.

  function paneSize() {
    const panes = ui.state.sideBySide ? 2 : 1;
    return {
      width: Math.max(1, Math.floor(ui.viewport.clientWidth / panes)),
      height: Math.max(1, ui.viewport.clientHeight),
    };
  }

  let renderRequested = false;
  function requestRender() {
    if (renderRequested) return;
    renderRequested = true;
    requestAnimationFrame(() => {
      renderRequested = false;
      render();
    });
  }

  function render() {
    const renderer = ui.renderer;
    const width = ui.viewport.clientWidth, height = ui.viewport.clientHeight;
    if (!width || !height) return;
    const canvas = renderer.domElement;
    if (canvas.width !== Math.floor(width * renderer.getPixelRatio()) ||
        canvas.height !== Math.floor(height * renderer.getPixelRatio())) {
      renderer.setSize(width, height, false);
    }
    const { width: paneWidth } = paneSize();
    ui.camera.aspect = paneWidth / height;
    placeCamera();
    ui.camera.updateProjectionMatrix();
    renderer.setScissorTest(false);
    renderer.clear();
    renderer.setScissorTest(true);
    const visible = ui.panes.filter((p) => !p.el.hidden);
    for (const [i, pane] of visible.entries()) {
      for (const other of ui.panes) other.group.visible = other === pane;
      renderer.setViewport(i * paneWidth, 0, paneWidth, height);
      renderer.setScissor(i * paneWidth, 0, paneWidth, height);
      renderer.render(ui.scene, ui.camera);
    }
    renderer.setScissorTest(false);
    api.ready = true;
  }

  // ---------------------------------------------------------------------------------------------
  // Public entry points.

  window.ICE_VIEWER = { register, start };

  Object.assign(api, {
    setMesh, setMethod, setOther, setField, setEdges, setSideBySide,
    // The current choices and what there is to choose from.
    state() {
      if (!ui || !meshes.length) return null;
      const s = ui.state;
      return {
        mesh: currentMesh().name, meshes: meshes.map((m) => m.name),
        method: s.method,
        methods: currentMesh().methods.map((m) => ({ name: m.name, status: m.status, message: m.message })),
        field: s.field, fields: fieldsFor(s.method).map((f) => f.name),
        edges: s.edges, sideBySide: s.sideBySide, other: s.sideBySide ? s.other : null,
      };
    },
  });
})();
