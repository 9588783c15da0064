// Measures how long viewer pages take to show their first frame in headless Chromium.
//
//   mkdir /tmp/m && cp crates/view/examples/measure_load.mjs /tmp/m && cd /tmp/m
//   npm install playwright-core@1.49.1      # only this measurement needs npm
//   node measure_load.mjs /abs/path/PAGE.html...
//
// Prints, per run, the wall time from navigation to `data-ready="1"`, the page's own
// timings (ms since navigation start when the script started, the data were decoded, three.js
// was imported, WebGL was up; loadMs = first frame drawn) and the mean time to draw a frame.
import { chromium } from 'playwright-core';
// One fresh browser per run (SwiftShader takes seconds to create a second WebGL context in the
// same headless browser, which says nothing about the page).
for (const file of process.argv.slice(2)) {
  for (let run = 0; run < 3; run++) {
    const browser = await chromium.launch({ executablePath: '/usr/bin/chromium', args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--disable-gpu'] });
    const page = await browser.newPage({ viewport: { width: 1100, height: 800 } });
    const t0 = Date.now();
    await page.goto('file://' + file);
    await page.waitForFunction(() => document.body.dataset.ready === '1', null, { timeout: 60000 });
    const wall = Date.now() - t0;
    const s = await page.evaluate(() => ({ t: JSON.stringify(window.locapViewer.timings), loadMs: window.locapViewer.loadMs, spheres: window.locapViewer.spheresDrawn, err: window.locapViewer.error }));
    const step = await page.evaluate(() => { const t = performance.now(); for (let f = 0; f < 240; f++) window.locapViewer.setFrame(f * 50); return (performance.now() - t) / 240; });
    console.log(file.split('/').pop(), run, 'wall', wall, 'loadMs', s.loadMs, s.t, 'spheres', s.spheres, s.err, 'draw ms', step.toFixed(2));
    await browser.close();
  }
}
