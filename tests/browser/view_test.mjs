#!/usr/bin/env node
// Opens a report page from disk in headless Chromium and checks what a person would see: no
// errors, for every mesh and method a mesh filling a fair part of the 3D view in varied colours
// with red coarse edges (or, for a failed method, its message over the mesh), two filled panes
// side by side, and mouse controls that turn, zoom and reset the view.
//
// Usage: node tests/browser/view_test.mjs PAGE.html [--screenshot OUT.png]
// Exit: 0 pass, 1 fail (reasons printed), 2 cannot run here (no Chromium or no playwright-core).
// Chromium: $CHROMIUM, else /usr/bin/chromium. playwright-core: apps/viewer/node_modules
// (npm ci in apps/viewer).

import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { createRequire } from 'node:module';
import { fileURLToPath, pathToFileURL } from 'node:url';

const READY_TIMEOUT_MS = 60_000;
const WATCHDOG_MS = 180_000;
const VIEWPORT = { width: 1200, height: 800 };
// Thresholds of the checks: fractions of the canvas (or of its mesh pixels).
const MIN_MESH_FRACTION = 0.10;
const MIN_PANE_MESH_FRACTION = 0.05;   // of each half, side by side
const MIN_COLOUR_BINS = 5;              // hue x lightness bins holding >= 1% of the mesh pixels
const MIN_HUE_BINS = 3;                 // hue bins holding >= 1% of the mesh pixels
const MIN_EDGE_FRACTION = 0.003;
const MIN_REDDISH_FRACTION = 0.6;       // of the pixels the edges change

// Without a GPU, WebGL runs on SwiftShader (software). It is asked for explicitly: Chromium's
// automatic fallback to it is deprecated (it warns on each page) and due to go.
const CHROMIUM_FLAGS = [
  '--no-sandbox', '--disable-gpu', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
  '--disable-quic', '--no-first-run', '--disable-background-networking',
  '--disable-component-update', '--disable-sync',
];

const here = path.dirname(fileURLToPath(import.meta.url));
const viewerDir = path.resolve(here, '../../apps/viewer');

function usage(message) {
  console.error(`${message}\nusage: node tests/browser/view_test.mjs PAGE.html [--screenshot OUT.png]`);
  process.exit(1);
}

function parseArgs(argv) {
  const args = { page: null, screenshot: null };
  for (let i = 0; i < argv.length; i++) {
    if (argv[i] === '--screenshot') {
      args.screenshot = argv[++i];
      if (!args.screenshot) usage('--screenshot needs a file name');
    } else if (argv[i].startsWith('-')) {
      usage(`unknown option ${argv[i]}`);
    } else if (args.page) {
      usage('one page only');
    } else {
      args.page = argv[i];
    }
  }
  if (!args.page) usage('no page given');
  if (!fs.existsSync(args.page)) usage(`no such page: ${args.page}`);
  return args;
}

function cannotRun(message) {
  console.log(`SKIP: ${message}`);
  process.exit(2);
}

function loadPlaywright() {
  const require = createRequire(path.join(viewerDir, 'package.json'));
  try {
    return require('playwright-core');
  } catch {
    return cannotRun(`playwright-core is not installed in ${viewerDir} (run npm ci there)`);
  }
}

function findChromium() {
  const executable = process.env.CHROMIUM || '/usr/bin/chromium';
  try {
    fs.accessSync(executable, fs.constants.X_OK);
  } catch {
    cannotRun(`no Chromium at ${executable} (set CHROMIUM or install Debian's chromium)`);
  }
  return executable;
}

// ------------------------------------------------------------------------------------------------
// In-page pixel analysis, installed as window.iceTestProbe. Playwright sends the function's source
// to the page, so it uses only the page's globals.

function installProbe() {
  const canvas = document.querySelector('.ice-viewport canvas');
  // The WebGL canvas keeps its last frame (preserveDrawingBuffer): copy it through a 2D canvas.
  const grab = () => {
    const c = document.createElement('canvas');
    c.width = canvas.width;
    c.height = canvas.height;
    const g = c.getContext('2d', { willReadFrequently: true });
    g.drawImage(canvas, 0, 0);
    return g.getImageData(0, 0, c.width, c.height);
  };
  const pixel = (image, x, y) => {
    const k = 4 * (y * image.width + x);
    return [image.data[k], image.data[k + 1], image.data[k + 2]];
  };
  const distance = (a, b) => Math.max(Math.abs(a[0] - b[0]), Math.abs(a[1] - b[1]), Math.abs(a[2] - b[2]));
  let kept = null;

  // Over the columns [from, to) (fractions of the width): the share of pixels that differ from
  // the background (the most common colour of the border) and how many colour bins the mesh
  // pixels fill. With edgesOff, also grabs the canvas with the coarse edges hidden and compares.
  function measure({ from, to, edgesOff }) {
    const withEdges = grab();
    const { width, height } = withEdges;
    const x0 = Math.floor(from * width), x1 = Math.floor(to * width);
    const total = (x1 - x0) * height;
    let image = withEdges;
    let edges = null;
    if (edgesOff) {
      const before = window.iceViewer.state().edges;
      window.iceViewer.setEdges(false);
      image = grab();
      window.iceViewer.setEdges(before);
      let changed = 0, reddish = 0;
      for (let y = 0; y < height; y++) {
        for (let x = x0; x < x1; x++) {
          const a = pixel(withEdges, x, y);
          if (distance(a, pixel(image, x, y)) <= 24) continue;
          changed++;
          if (a[0] >= 120 && a[0] >= a[1] + 50 && a[0] >= a[2] + 50) reddish++;
        }
      }
      edges = { changed: changed / total, reddish: changed ? reddish / changed : 0 };
    }

    const counts = new Map();
    const count = (x, y) => { const key = pixel(image, x, y).join(); counts.set(key, (counts.get(key) || 0) + 1); };
    for (let x = x0; x < x1; x++) { count(x, 0); count(x, height - 1); }
    for (let y = 0; y < height; y++) { count(x0, y); count(x1 - 1, y); }
    const background = [...counts.entries()].sort((p, q) => q[1] - p[1])[0][0].split(',').map(Number);

    let mesh = 0;
    const bins = new Map(), hues = new Map();
    for (let y = 0; y < height; y++) {
      for (let x = x0; x < x1; x++) {
        const rgb = pixel(image, x, y);
        if (distance(rgb, background) <= 8) continue;
        mesh++;
        // HSL: hue in 12 bins of 30 degrees (greys apart), lightness in 5 bins.
        const [r, g, b] = rgb.map((c) => c / 255);
        const max = Math.max(r, g, b), min = Math.min(r, g, b);
        const l = (max + min) / 2, d = max - min;
        const s = d === 0 ? 0 : d / (1 - Math.abs(2 * l - 1));
        let hue = 12;
        if (s > 0.15) {
          const h = max === r ? ((g - b) / d) % 6 : max === g ? (b - r) / d + 2 : (r - g) / d + 4;
          hue = Math.floor(((h * 60 + 360) % 360) / 30);
        }
        const key = hue * 5 + Math.min(4, Math.floor(l * 5));
        bins.set(key, (bins.get(key) || 0) + 1);
        if (hue < 12) hues.set(hue, (hues.get(hue) || 0) + 1);
      }
    }
    const atLeastOnePercent = (map) => [...map.values()].filter((n) => n >= 0.01 * mesh).length;
    return {
      background, mesh: mesh / total,
      colourBins: atLeastOnePercent(bins), hueBins: atLeastOnePercent(hues), edges,
    };
  }

  // keep() remembers the canvas; changed() is the share of pixels that differ from it since.
  function keep() { kept = grab(); }
  function changed() {
    const now = grab();
    if (now.width !== kept.width || now.height !== kept.height) return 1;
    let n = 0;
    for (let y = 0; y < now.height; y++) {
      for (let x = 0; x < now.width; x++) if (distance(pixel(now, x, y), pixel(kept, x, y)) > 24) n++;
    }
    return n / (now.width * now.height);
  }

  window.iceTestProbe = { measure, keep, changed };
}

// ------------------------------------------------------------------------------------------------

const percent = (x) => `${(100 * x).toFixed(1)}%`;

async function main() {
  const args = parseArgs(process.argv.slice(2));
  const { chromium } = loadPlaywright();
  const executablePath = findChromium();
  const started = Date.now();
  const failures = [];
  const notes = [];
  const fail = (message) => failures.push(message);

  const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'ice-view-test-'));
  let context = null;
  const watchdog = setTimeout(() => {
    console.log(`FAIL: the test did not finish in ${WATCHDOG_MS / 1000} s`);
    fs.rmSync(userDataDir, { recursive: true, force: true });
    process.exit(1);
  }, WATCHDOG_MS);
  try {
    context = await chromium.launchPersistentContext(userDataDir, {
      executablePath, headless: true, args: CHROMIUM_FLAGS, viewport: VIEWPORT, deviceScaleFactor: 1,
    });
    const page = context.pages()[0] || await context.newPage();
    // Console errors and uncaught exceptions fail the test; nothing of type "error" is ignored
    // (the page sets an empty favicon, so it asks for no favicon file). Warnings, such as
    // SwiftShader's "GPU stall due to ReadPixels", do not count.
    page.on('console', (msg) => {
      if (msg.type() === 'error') fail(`console error: ${msg.text()}`);
    });
    page.on('pageerror', (error) => fail(`page error: ${error.message}`));
    // The page must work offline: anything but file: and data: URLs is a failure.
    page.on('request', (request) => {
      if (!/^(file|data):/.test(request.url())) fail(`network request: ${request.url()}`);
    });
    page.on('requestfailed', (request) => fail(`failed to load ${request.url()}: ${request.failure().errorText}`));

    const opened = Date.now();
    await page.goto(pathToFileURL(path.resolve(args.page)).href);
    try {
      await page.waitForFunction(() => window.iceViewer && (window.iceViewer.ready || window.iceViewer.errors.length > 0),
        null, { timeout: READY_TIMEOUT_MS, polling: 100 });
    } catch {
      fail(`the viewer was not ready after ${READY_TIMEOUT_MS / 1000} s`);
      return report(failures, notes, started);
    }
    const ready = await page.evaluate(() => window.iceViewer.ready);
    notes.push(`${ready ? 'ready' : 'errors'} ${((Date.now() - opened) / 1000).toFixed(1)} s after opening ` +
      `the page (browser started in ${((opened - started) / 1000).toFixed(1)} s)`);
    const renderer = await page.evaluate(() => {
      const gl = document.createElement('canvas').getContext('webgl2');
      const info = gl && gl.getExtension('WEBGL_debug_renderer_info');
      return gl ? gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER) : 'none';
    });
    notes.push(`Chromium ${context.browser().version()}, WebGL: ${renderer}`);
    if (args.screenshot) {
      await page.screenshot({ path: args.screenshot });
      notes.push(`screenshot: ${args.screenshot}`);
    }
    for (const e of await page.evaluate(() => window.iceViewer.errors)) fail(`viewer error: ${e}`);
    const initial = await page.evaluate(() => window.iceViewer.state());
    if (!initial) fail('the viewer has no mesh');
    // A page that failed to load is not worth driving further.
    if (failures.length) return report(failures, notes, started);
    await page.evaluate(installProbe);
    for (const meshName of initial.meshes) {
      await checkMesh(page, meshName, fail, notes);
    }
    await page.evaluate((s) => {
      window.iceViewer.setMesh(s.mesh);
      window.iceViewer.setMethod(s.method);
    }, initial);
    await checkMouse(page, fail, notes);
    for (const e of await page.evaluate(() => window.iceViewer.errors)) fail(`viewer error after the checks: ${e}`);
  } catch (error) {
    fail(`test error: ${error.message}`);
  } finally {
    clearTimeout(watchdog);
    if (context) await context.close();
    fs.rmSync(userDataDir, { recursive: true, force: true });
  }
  return report(failures, notes, started);
}

const measure = (page, options) => page.evaluate((o) => window.iceTestProbe.measure(o), options);
const changed = (page) => page.evaluate(() => window.iceTestProbe.changed());
// Renders triggered by mouse input happen at the next animation frame.
const nextFrames = (page) => page.evaluate(() => new Promise((resolve) =>
  requestAnimationFrame(() => requestAnimationFrame(resolve))));

// Every method of one mesh, then the first two side by side.
async function checkMesh(page, meshName, fail, notes) {
  const state = await page.evaluate((name) => window.iceViewer.setMesh(name), meshName);
  for (const method of state.methods) {
    const where = `${meshName}/${method.name}`;
    await page.evaluate((name) => window.iceViewer.setMethod(name), method.name);
    const ok = method.status === 'ok';
    const m = await measure(page, { from: 0, to: 1, edgesOff: ok });
    let line = `${where}: mesh on ${percent(m.mesh)} of the canvas, ${m.colourBins} colour bins, ${m.hueBins} hues`;
    if (m.mesh < MIN_MESH_FRACTION) fail(`${where}: the mesh covers ${percent(m.mesh)} of the canvas (< ${percent(MIN_MESH_FRACTION)})`);
    if (ok) {
      if (m.colourBins < MIN_COLOUR_BINS || m.hueBins < MIN_HUE_BINS) {
        fail(`${where}: too few colours (${m.colourBins} colour bins, ${m.hueBins} hues with >= 1% of the mesh)`);
      }
      line += `, edges change ${percent(m.edges.changed)} (${percent(m.edges.reddish)} of them reddish)`;
      if (m.edges.changed < MIN_EDGE_FRACTION || m.edges.reddish < MIN_REDDISH_FRACTION) {
        fail(`${where}: coarse edges not seen (they change ${percent(m.edges.changed)} of the canvas, ` +
          `${percent(m.edges.reddish)} reddish)`);
      }
    } else {
      const expected = `${method.name} failed on this mesh`;
      const overlay = page.locator('.ice-overlay:visible', { hasText: expected });
      if (await overlay.count() !== 1) fail(`${where}: no visible "${expected}" message`);
      else line += `, says "${await overlay.innerText()}"`;
    }
    notes.push(line);
  }
  if (state.methods.length < 2) return;
  await page.evaluate((methods) => {
    window.iceViewer.setMethod(methods[0].name);
    window.iceViewer.setSideBySide(true);
  }, state.methods);
  const halves = [await measure(page, { from: 0, to: 0.5, edgesOff: false }),
    await measure(page, { from: 0.5, to: 1, edgesOff: false })];
  const names = await page.evaluate(() => { const s = window.iceViewer.state(); return [s.method, s.other]; });
  halves.forEach((h, i) => {
    if (h.mesh < MIN_PANE_MESH_FRACTION) {
      fail(`${meshName}: side by side, the ${names[i]} pane shows the mesh on ${percent(h.mesh)} of it`);
    }
  });
  notes.push(`${meshName}: side by side ${names.join(' | ')}: mesh on ${halves.map((h) => percent(h.mesh)).join(' | ')}`);
  await page.evaluate(() => window.iceViewer.setSideBySide(false));
}

// The mouse controls: a drag turns the mesh, a double-click brings the first view back, the
// wheel zooms in.
async function checkMouse(page, fail, notes) {
  const box = await page.locator('.ice-viewport').boundingBox();
  const x = box.x + box.width / 2, y = box.y + box.height / 2;
  await page.evaluate(() => window.iceTestProbe.keep());
  const before = await measure(page, { from: 0, to: 1, edgesOff: false });
  await page.mouse.move(x, y);
  await page.mouse.down();
  await page.mouse.move(x + 120, y + 40, { steps: 6 });
  await page.mouse.up();
  await nextFrames(page);
  const dragged = await changed(page);
  await page.mouse.dblclick(x, y);
  await nextFrames(page);
  const reset = await changed(page);
  await page.mouse.wheel(0, -400);
  await nextFrames(page);
  const zoomed = await measure(page, { from: 0, to: 1, edgesOff: false });
  await page.mouse.dblclick(x, y);
  await nextFrames(page);
  if (dragged < 0.05) fail(`a mouse drag changed ${percent(dragged)} of the canvas (< 5%)`);
  if (reset > 0.005) fail(`after a double-click ${percent(reset)} of the canvas differs from the first view`);
  if (zoomed.mesh < before.mesh * 1.1) fail(`the wheel did not zoom in (mesh on ${percent(before.mesh)}, then ${percent(zoomed.mesh)})`);
  notes.push(`mouse: drag changes ${percent(dragged)}, double-click restores (${percent(reset)} differ), ` +
    `wheel zooms the mesh from ${percent(before.mesh)} to ${percent(zoomed.mesh)}`);
}

function report(failures, notes, started) {
  for (const note of notes) console.log(note);
  const seconds = ((Date.now() - started) / 1000).toFixed(1);
  if (failures.length) {
    for (const f of failures) console.log(`FAIL: ${f}`);
    console.log(`view test failed (${failures.length} problems, ${seconds} s)`);
    return 1;
  }
  console.log(`view test passed (${seconds} s)`);
  return 0;
}

process.exitCode = await main();
