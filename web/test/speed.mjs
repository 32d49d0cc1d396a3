// The page's time per step against the native run of the same scene code, in one sitting.
//
//   node web/test/speed.mjs [STEPS] [RUNS]
//
// Needs the release wasm build and the native program (cargo build --release -p softfem-web),
// and `npm ci` in web/. Each of RUNS rounds (default 5) times STEPS steps (default 120) of the
// default scene from t = 0, natively (target/release/web-timing) and in headless Chromium
// (`playground.bench`, performance.now() around each sf_step call), alternating, then prints
// the minimum and median of each and their ratios.

import { execFileSync } from 'node:child_process';
import { cpus } from 'node:os';
import { join } from 'node:path';
import { ROOT, launch, open, serve } from './harness.mjs';

const steps = Number(process.argv[2] ?? 120);
const runs = Number(process.argv[3] ?? 5);
const native = join(ROOT, 'target', 'release', 'web-timing');

const server = await serve();
const browser = await launch();
const times = { native: [], wasm: [] };
try {
  const { page } = await open(browser.context, server.url, '?manual');
  const version = await page.evaluate(() => navigator.userAgent);
  for (let k = 1; k <= runs; k++) {
    const output = execFileSync(native, [String(steps), '1'], { encoding: 'utf8' });
    const ms = Number(/run 1: ([0-9.]+) ms/.exec(output)?.[1]);
    times.native.push(ms);
    const wasm = await page.evaluate((n) => window.playground.bench(n), steps);
    times.wasm.push(wasm);
    console.log(`round ${k}: native ${ms.toFixed(2)} ms, wasm ${wasm.toFixed(2)} ms per step`);
  }
  console.log(`${steps} steps a run, ${runs} runs; CPU ${cpus()[0]?.model} (${cpus().length} ` +
    `logical); ${version.match(/Chrome\/[0-9.]+/)?.[0] ?? version}`);
} finally {
  await browser.close();
  await server.close();
}
const min = (a) => Math.min(...a);
const median = (a) => [...a].sort((x, y) => x - y)[Math.floor(a.length / 2)];
for (const [name, f] of [['min', min], ['median', median]]) {
  const [n, w] = [f(times.native), f(times.wasm)];
  console.log(`${name}: native ${n.toFixed(2)} ms, wasm ${w.toFixed(2)} ms, ratio ` +
    `${(w / n).toFixed(2)}`);
}
