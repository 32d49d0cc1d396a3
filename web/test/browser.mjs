// The playground page in a real browser: Debian's headless Chromium (WebGL2 from SwiftShader)
// loads web/index.html from a local server on 127.0.0.1, steps a fixed number of frames of each
// scene (the playground, then the pile) with a scripted drag through real pointer events, and
// checks what the page reports.
//
//   node web/test/browser.mjs [--screenshot PATH] [--pile-screenshot PATH] [--reference URL]
//
// Needs the release wasm build (see docs/guide/08-web-browser.md) and `npm ci` in web/.
// Writes the screenshots to PATH (default target/web-test/playground.png and pile.png next to
// it). With `--reference`, also loads the module at URL (relative to web/; CI gives a scalar
// debug build) and checks that both reach the same positions, bit for bit (FNV-1a digests),
// after REFERENCE_STEPS steps of the playground with each stepper and PILE_REFERENCE_STEPS of
// the pile with each of the World's: the SIMD128 lanes give the scalar bits. Exits non-zero if
// any check fails.

import { mkdir } from 'node:fs/promises';
import { dirname, join, resolve } from 'node:path';
import { ROOT, launch, open, serve } from './harness.mjs';

// Frames: the bodies land, a body is lifted by the pointer in steps, held, let go, and left.
const LAND = 90;
const DRAG_MOVES = 20;
const FRAMES_PER_MOVE = 3;
const HOLD = 30;
const SETTLE = 180;
const LIFT_PX = 100; // how far the pointer moves up while dragging (CSS pixels)
const PIXEL_VARIANCE_FLOOR = 100; // luminance^2 (0..255); a blank or flat picture is ~0

// The pile: the balls land, one is lifted by the pointer and let go.
const PILE_LAND = 60;
const PILE_DRAG_MOVES = 10;
const PILE_HOLD = 15;
const PILE_SETTLE = 30;
// CSS pixels up: 13 cm in the drag plane facing the camera, about 9 cm up and 10 cm away.
const PILE_LIFT_PX = 150;

const REFERENCE_STEPS = 10;
// Enough for the lowest balls to reach the ground and each other (contact pairs from the fifth
// step); the scalar debug module takes about a second a step of the explicit stepper here.
const PILE_REFERENCE_STEPS = 8;

const argv = process.argv.slice(2);
const option = (name) => (argv.includes(name) ? argv[argv.indexOf(name) + 1] : undefined);
const screenshot = resolve(ROOT, option('--screenshot') ?? 'target/web-test/playground.png');
const pileScreenshot = resolve(ROOT, option('--pile-screenshot') ??
  join(dirname(screenshot), 'pile.png'));
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

  // The pile: switched to by the Scene control, as a user would.
  await page.selectOption('#scene', '1');
  const pileStart = await page.evaluate(() => window.playground.stats());
  let pileMaxPairs = 0;
  let pileLanded = pileStart;
  for (let k = 0; k < PILE_LAND / 10; k++) {
    pileLanded = await advance(10);
    pileMaxPairs = Math.max(pileMaxPairs, pileLanded.contactPairs);
  }
  const balls = await page.evaluate(() => window.playground.positions());
  const pileTop = balls.reduce((a, b) => (b[2] > a[2] ? b : a));
  const [px, py] = await page.evaluate((p) => window.playground.screenOf(p), pileTop);
  await page.mouse.move(px, py);
  await page.mouse.down();
  const pileGrabbed = await page.evaluate(() => window.playground.stats());
  for (let k = 1; k <= PILE_DRAG_MOVES; k++) {
    await page.mouse.move(px, py - (k * PILE_LIFT_PX) / PILE_DRAG_MOVES);
    pileMaxPairs = Math.max(pileMaxPairs, (await advance(FRAMES_PER_MOVE)).contactPairs);
  }
  const pileHeld = await advance(PILE_HOLD);
  const pilePixels = await page.evaluate(() => window.playground.pixels());
  const pileReadout = await page.evaluate(() => document.getElementById('readout').textContent);
  await page.screenshot({ path: pileScreenshot });
  await page.mouse.up();
  let pileLast = pileHeld;
  for (let k = 0; k < PILE_SETTLE / 10; k++) {
    pileLast = await advance(10);
    pileMaxPairs = Math.max(pileMaxPairs, pileLast.contactPairs);
  }
  const pileFrames = PILE_LAND + PILE_DRAG_MOVES * FRAMES_PER_MOVE + PILE_HOLD + PILE_SETTLE;
  const pileFinite = await page.evaluate(() => window.playground.positionsFinite());
  const pileErrors = await page.evaluate(() => window.playground.errors);
  const vbdOff = await page.evaluate(() =>
    document.querySelector('#stepper option[value="3"]').disabled &&
    !document.getElementById('note').hidden);

  check('pile: the Scene control switched to it', pileStart.scene === 1 && pileStart.steps === 0 &&
    pileStart.bodies === 6 && vbdOff, `scene ${pileStart.scene}, ${pileStart.bodies} bodies, ` +
    `${pileStart.tets} tets, VBD disabled with the note ${vbdOff}`);
  check('pile: frames stepped', pileLast.steps === pileFrames, `${pileLast.steps} of ${pileFrames}`);
  check('pile: no error', pileLast.errorCode === 0 && problems.length === 0 &&
    pileErrors.length === 0, `status ${pileLast.errorCode}, ` +
    `${problems.length + pileErrors.length} page errors` +
    [...problems, ...pileErrors].map((p) => `\n     ${p}`).join(''));
  check('pile: every position finite', pileFinite && pileLast.finite === 1,
    `render buffer ${pileFinite}, positions and velocities ${pileLast.finite === 1} ` +
    `(${pileLast.vertices} vertices, ${pileLast.tets} tets)`);
  check('pile: the balls touch', pileMaxPairs > 0 && pileLanded.contactPairs > 0,
    `${pileLanded.contactPairs} contact pairs after landing, at most ${pileMaxPairs}`);
  check('pile: the pointer grabbed a ball and lifted it', pileGrabbed.grabbing === 1 &&
    // 0.03 J: one ball (0.22 kg) 1.4 cm up.
    pileHeld.gravity > pileLanded.gravity + 0.03, `grabbing ${pileGrabbed.grabbing}, ` +
    `gravitational energy ${pileLanded.gravity.toFixed(3)} J landed, ` +
    `${pileHeld.gravity.toFixed(3)} J held`);
  check('pile: the picture is not blank', pilePixels.variance > PIXEL_VARIANCE_FLOOR,
    `luminance variance ${pilePixels.variance.toFixed(0)} (floor ${PIXEL_VARIANCE_FLOOR}), ` +
    `mean ${pilePixels.mean.toFixed(0)}; screenshot ${pileScreenshot}`);
  console.log(`pile readout while held: ${pileReadout.split('\n').slice(0, 4).join('; ')}`);

  if (reference) {
    const digests = (p) => p.evaluate(([n, m]) => [
      ...[0, 1, 2, 3].map((s) => window.playground.digest(n, s)),
      ...[0, 1, 2].map((s) => window.playground.digest(m, s, 1)),
    ], [REFERENCE_STEPS, PILE_REFERENCE_STEPS]);
    const ours = await digests(page);
    const { page: other } = await open(browser.context, server.url,
      `?manual&wasm=${encodeURIComponent(reference)}`);
    const theirs = await digests(other);
    const otherSimd = await other.evaluate(() => window.playground.simd());
    const same = (from, to) => ours.slice(from, to).every((d, k) => d !== null &&
      d === theirs[from + k]);
    check('the same positions as the reference module', same(0, 4), `${simd} against ` +
      `${otherSimd} (${reference}), ${REFERENCE_STEPS} steps each of explicit, relaxation, ` +
      `Newton, VBD: ${ours.slice(0, 4).join(' ')} against ${theirs.slice(0, 4).join(' ')}`);
    check('pile: the same positions as the reference module', same(4, 7), `${simd} against ` +
      `${otherSimd}, ${PILE_REFERENCE_STEPS} steps each of explicit, relaxation, Newton: ` +
      `${ours.slice(4).join(' ')} against ${theirs.slice(4).join(' ')}`);
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
