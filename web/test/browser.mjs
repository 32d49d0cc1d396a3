// The playground page in a real browser: Debian's headless Chromium (WebGL2 from SwiftShader)
// loads web/index.html from a local server on 127.0.0.1, steps a fixed number of frames with a
// scripted drag through real pointer events, and checks what the page reports.
//
//   node web/test/browser.mjs [--screenshot PATH] [--reference URL]
//
// Needs the release wasm build (see docs/guide/08-web-browser.md) and `npm ci` in web/.
// Writes the screenshot to PATH (default target/web-test/playground.png). With `--reference`,
// also loads the module at URL (relative to web/; CI gives a scalar debug build) and checks that
// both reach the same positions, bit for bit (FNV-1a digests), after REFERENCE_STEPS steps with
// each stepper: the SIMD128 lanes give the scalar bits. Exits non-zero if any check fails.

import { mkdir } from 'node:fs/promises';
import { dirname, resolve } from 'node:path';
import { ROOT, launch, open, serve } from './harness.mjs';

// Frames: the bodies land, a body is lifted by the pointer in steps, held, let go, and left.
const LAND = 90;
const DRAG_MOVES = 20;
const FRAMES_PER_MOVE = 3;
const HOLD = 30;
const SETTLE = 180;
const LIFT_PX = 100; // how far the pointer moves up while dragging (CSS pixels)
const PIXEL_VARIANCE_FLOOR = 100; // luminance^2 (0..255); a blank or flat picture is ~0

const REFERENCE_STEPS = 10;

const argv = process.argv.slice(2);
const option = (name) => (argv.includes(name) ? argv[argv.indexOf(name) + 1] : undefined);
const screenshot = resolve(ROOT, option('--screenshot') ?? 'target/web-test/playground.png');
const reference = option('--reference');

const started = Date.now();
const results = [];
function check(name, ok, measured) {
  results.push(ok);
  console.log(`${ok ? 'ok  ' : 'FAIL'} ${name}: ${measured}`);
}

const server = await serve();
const browser = await launch();
try {
  const { page, problems } = await open(browser.context, server.url, '?manual');
  const advance = (n) => page.evaluate((k) => window.playground.advance(k), n);
  const energy = (s) => s.kinetic + s.gravity + s.elastic;

  const landed = await advance(LAND);
  // The highest vertex of any body: on top, facing the elevated camera.
  const positions = await page.evaluate(() => window.playground.positions());
  const top = positions.reduce((a, b) => (b[2] > a[2] ? b : a));
  const [x, y] = await page.evaluate((p) => window.playground.screenOf(p), top);
  await page.mouse.move(x, y);
  await page.mouse.down();
  const grabbed = await page.evaluate(() => window.playground.stats());
  let lifted = grabbed;
  for (let k = 1; k <= DRAG_MOVES; k++) {
    await page.mouse.move(x + (k * LIFT_PX) / (2 * DRAG_MOVES), y - (k * LIFT_PX) / DRAG_MOVES);
    lifted = await advance(FRAMES_PER_MOVE);
  }
  const held = await advance(HOLD);
  // The picture while the body hangs from the pointer: the screenshot and its variance.
  const pixels = await page.evaluate(() => window.playground.pixels());
  await mkdir(dirname(screenshot), { recursive: true });
  await page.screenshot({ path: screenshot });
  await page.mouse.up();
  const released = await page.evaluate(() => window.playground.stats());
  // The energy after release: the largest kinetic energy and the last total.
  let peakKinetic = released.kinetic;
  let last = released;
  for (let k = 0; k < SETTLE / 10; k++) {
    last = await advance(10);
    peakKinetic = Math.max(peakKinetic, last.kinetic);
  }
  const frames = LAND + DRAG_MOVES * FRAMES_PER_MOVE + HOLD + SETTLE;
  const finite = await page.evaluate(() => window.playground.positionsFinite());
  const pageErrors = await page.evaluate(() => window.playground.errors);

  check('frames stepped', last.steps === frames, `${last.steps} of ${frames}`);
  check('no error', last.errorCode === 0 && problems.length === 0 && pageErrors.length === 0,
    `status ${last.errorCode}, ${problems.length + pageErrors.length} page errors` +
    [...problems, ...pageErrors].map((p) => `\n     ${p}`).join(''));
  check('every position finite', finite && last.finite === 1,
    `render buffer ${finite}, positions and velocities ${last.finite === 1} ` +
    `(${last.vertices} vertices, ${last.tets} tets)`);
  check('the pointer grabbed a body and lifted it', grabbed.grabbing === 1 &&
    held.gravity > landed.gravity + 1, `grabbing ${grabbed.grabbing}, gravitational energy ` +
    `${landed.gravity.toFixed(2)} J landed, ${held.gravity.toFixed(2)} J held ` +
    `(${lifted.steps} steps at the end of the drag)`);
  check('energy decayed after the release', energy(last) < energy(released) &&
    last.kinetic < 0.25 * peakKinetic,
    `total ${energy(released).toFixed(3)} J at release, ${energy(last).toFixed(3)} J ` +
    `${SETTLE} frames later; kinetic peak ${peakKinetic.toFixed(3)} J, last ` +
    `${last.kinetic.toFixed(4)} J`);
  check('the picture is not blank', pixels.variance > PIXEL_VARIANCE_FLOOR,
    `luminance variance ${pixels.variance.toFixed(0)} (floor ${PIXEL_VARIANCE_FLOOR}), mean ` +
    `${pixels.mean.toFixed(0)}, ${pixels.width}x${pixels.height}; screenshot ${screenshot}`);
  const simd = await page.evaluate(() => window.playground.simd());
  if (reference) {
    const digests = (p) => p.evaluate((n) => [0, 1, 2, 3].map((s) => window.playground.digest(n, s)),
      REFERENCE_STEPS);
    const ours = await digests(page);
    const { page: other } = await open(browser.context, server.url,
      `?manual&wasm=${encodeURIComponent(reference)}`);
    const theirs = await digests(other);
    const otherSimd = await other.evaluate(() => window.playground.simd());
    check('the same positions as the reference module', ours.every((d, k) => d !== null &&
      d === theirs[k]), `${simd} against ${otherSimd} (${reference}), ${REFERENCE_STEPS} steps ` +
      `each of explicit, relaxation, Newton, VBD: ${ours.join(' ')} against ${theirs.join(' ')}`);
  }
  console.log(`converged share ${(100 * last.convergedShare).toFixed(1)} %, module ${simd}, ` +
    `${((Date.now() - started) / 1000).toFixed(1)} s in all`);
} finally {
  await browser.close();
  await server.close();
}
const failed = results.filter((ok) => !ok).length;
console.log(`browser: ${results.length - failed} passed, ${failed} failed`);
process.exit(failed === 0 ? 0 : 1);
