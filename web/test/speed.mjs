// The page's time per step against the native run of the same scene code, in one sitting.
//
//   node web/test/speed.mjs [--steps N] [--runs R] [--steppers 0,1,2,3] [--scene pile]
//                           [--wasm URL]
//
// Needs the release wasm build and the native program (cargo build --release -p softfem-web),
// and `npm ci` in web/. For each stepper (0 explicit, 1 relaxation, 2 Newton, 3 VBD; default
// all, for the pile 0,1,2: its World refuses VBD), each of R rounds (default 5) times N steps
// (default 60) of the scene (the playground, or with `--scene pile` the pile) from t = 0 at the
// page's default settings, natively (target/release/web-timing) and in headless Chromium
// (`playground.bench`: performance.now() around each sf_step call), alternating, then prints the
// minimum and the median of each and their ratios. Both sides are warm: the native time is the
// second of two runs in one process, and the page runs the scene once before the rounds (a
// first run pays for fresh memory pages, VBD's colouring and the first compilation). `--wasm`
// loads another build of the module (a URL relative to web/).

import { execFileSync } from 'node:child_process';
import { cpus } from 'node:os';
import { join } from 'node:path';
import { ROOT, launch, open, serve } from './harness.mjs';

const option = (name, fallback) => {
  const at = process.argv.indexOf(`--${name}`);
  return at >= 0 ? process.argv[at + 1] : fallback;
};
const steps = Number(option('steps', 60));
const runs = Number(option('runs', 5));
const scene = { playground: 0, pile: 1 }[option('scene', 'playground')];
if (scene === undefined) throw new Error('--scene is playground or pile');
const steppers = option('steppers', scene === 1 ? '0,1,2' : '0,1,2,3').split(',').map(Number);
const wasmUrl = option('wasm', null);
const NAMES = ['explicit', 'relaxation', 'Newton', 'VBD'];
const native = join(ROOT, 'target', 'release', 'web-timing');

const min = (a) => Math.min(...a);
const median = (a) => [...a].sort((x, y) => x - y)[Math.floor(a.length / 2)];

const server = await serve();
const browser = await launch();
const rows = [];
try {
  const query = `?manual${wasmUrl ? `&wasm=${encodeURIComponent(wasmUrl)}` : ''}`;
  const { page } = await open(browser.context, server.url, query);
  const version = await page.evaluate(() => navigator.userAgent);
  for (const stepper of steppers) {
    const times = { native: [], wasm: [] };
    await page.evaluate(([n, s, k]) => window.playground.bench(n, s, k), [steps, stepper, scene]);
    for (let k = 1; k <= runs; k++) {
      const output = execFileSync(native, [String(steps), '2', String(stepper), String(scene)],
        { encoding: 'utf8' });
      times.native.push(Number(/run 2: ([0-9.]+) ms/.exec(output)?.[1]));
      times.wasm.push(await page.evaluate(([n, s, k]) => window.playground.bench(n, s, k),
        [steps, stepper, scene]));
      console.log(`${NAMES[stepper]} round ${k}: native ${times.native.at(-1).toFixed(2)} ms, ` +
        `wasm ${times.wasm.at(-1).toFixed(2)} ms per step`);
    }
    rows.push([NAMES[stepper], min(times.native), min(times.wasm), median(times.native),
      median(times.wasm)]);
  }
  console.log(`${['playground', 'pile'][scene]}, ${steps} steps a run, ${runs} runs; CPU ${cpus()[0]?.model} (${cpus().length} ` +
    `logical); ${version.match(/Chrome\/[0-9.]+/)?.[0] ?? version}`);
} finally {
  await browser.close();
  await server.close();
}
console.log('| stepper | native min | wasm min | ratio | native median | wasm median | ratio |');
console.log('| --- | --- | --- | --- | --- | --- | --- |');
for (const [name, nMin, wMin, nMed, wMed] of rows) {
  const ms = (x) => `${x.toFixed(1)} ms`;
  console.log(`| ${name} | ${ms(nMin)} | ${ms(wMin)} | ${(wMin / nMin).toFixed(2)} | ` +
    `${ms(nMed)} | ${ms(wMed)} | ${(wMed / nMed).toFixed(2)} |`);
}
