#!/usr/bin/env node
// Opens viewer pages in headless Chromium (Debian's chromium, driven by playwright-core) and checks
// what each page reports on itself (window.amtViewerReport, viewer.js) and what it draws.
//
//   node viewer/check_page.mjs URL... [--meshes N] [--apparel] [--screenshot FILE] [--report FILE]
//
// Every page (one browser, a page each) must become "ready" with N meshes (default: at least 1), every
// file loaded with at least one frame, no error (a file that does not load, WebGL, an exception,
// console.error), and a screenshot that is not blank (more than 1 % of its pixels away from the
// background; with --apparel, some pixels of the apparel tint's blue). --screenshot saves the first
// page's. Each page's report is printed (files, frames, vertices, apparel, fps, format, errors, PMD_a readout);
// --report writes every page's whole report (window.amtViewerReport) as a JSON list, in the order of the URLs.
//
// Exit status: 0 when every check passes, 1 when one fails (the reason on stderr), 77 when Chromium
// cannot start (the test is then skipped, with the reason, or fails when AMT_REQUIRE_BROWSER is set).
// The browser is AMT_CHROMIUM or /usr/bin/chromium.
import { chromium } from 'playwright-core';
import { writeFile } from 'node:fs/promises';

const args = process.argv.slice(2);
const valued = new Set(['--meshes', '--screenshot', '--report', '--timeout']);
const urls = [], options = {};
for (let k = 0; k < args.length; ++k) {
  if (valued.has(args[k])) options[args[k]] = args[++k];
  else if (args[k].startsWith('--')) options[args[k]] = true;
  else urls.push(args[k]);
}
if (urls.length === 0) {
  console.error('usage: node check_page.mjs URL... [--meshes N] [--apparel] [--screenshot FILE] [--report FILE]');
  process.exit(2);
}
const meshes = options['--meshes'];
const timeout = Number(options['--timeout'] ?? 60000);

// A failed check: thrown, so that the browser is closed before the exit.
function failed(reason) {
  throw new Error(reason);
}

const executablePath = process.env.AMT_CHROMIUM || '/usr/bin/chromium';
let browser;
try {
  browser = await chromium.launch({
    executablePath,
    headless: true,
    // No GPU here: WebGL through SwiftShader, Chromium's software renderer.
    args: ['--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist', '--no-sandbox'],
    timeout: 30000,
  });
} catch (error) {
  console.log(`check_page: SKIP: Chromium (${executablePath}) cannot start: ${error.message.split('\n')[0]}`);
  process.exit(77);
}

// Loads `url`, prints its report and checks it; `screenshotPath` saves the screenshot.
async function checkPage(url, screenshotPath) {
  const page = await browser.newPage({ viewport: { width: 960, height: 600 } });
  const consoleErrors = [];
  page.on('console', (message) => { if (message.type() === 'error') consoleErrors.push(message.text()); });
  page.on('pageerror', (error) => consoleErrors.push('page error: ' + error.message));
  const started = Date.now();
  await page.goto(url, { timeout });
  try {
    await page.waitForFunction(() => window.amtViewerReport && window.amtViewerReport.status !== 'loading' &&
                                     (window.amtViewerReport.status === 'error' || window.amtViewerReport.renderedFrames > 2),
                               null, { timeout });
  } catch (error) {
    const report = await page.evaluate(() => window.amtViewerReport ?? null);
    failed(`${url}: the page did not finish loading in ${timeout} ms (report: ${JSON.stringify(report)})`);
  }
  const report = await page.evaluate(() => window.amtViewerReport);
  reports.push(report);
  console.log(`check_page: ${url}: ${report.status} after ${Date.now() - started} ms: ${report.meshes} meshes, ` +
              `${report.framesLoaded} frames loaded, frame time ${report.frameTimeMs?.toFixed(2)} ms, ` +
              `${report.errors.length} errors`);
  for (const f of report.files) {
    console.log(`  ${f.file} (${f.role}): ${f.frames ?? '-'} frames, ${f.vertices ?? '-'} vertices, ` +
                `${f.apparelVertices ?? '-'} apparel, ${f.fps ?? '-'} fps, ${f.format ?? '-'}` +
                `${f.error ? ', error: ' + f.error : ''}`);
  }
  for (const e of report.errors) console.log('  error: ' + e);
  for (const e of consoleErrors) console.log('  console: ' + e);
  if (Object.keys(report.pmdA).length) console.log('  PMD_a at frame ' + report.frame + ': ' + JSON.stringify(report.pmdA));

  if (report.status !== 'ready') failed(`${url}: expected status ready, found ${report.status}: ${report.errors.join('; ')}`);
  if (consoleErrors.length) failed(`${url}: console errors: ` + consoleErrors.join('; '));
  if (meshes !== undefined ? report.meshes !== Number(meshes) : report.meshes < 1) {
    failed(`${url}: expected ${meshes ?? 'at least 1'} meshes, found ${report.meshes}`);
  }
  for (const f of report.files) if (!(f.frames >= 1)) failed(`${f.file}: expected frames loaded, found none`);
  const png = await page.screenshot();
  if (screenshotPath) await writeFile(screenshotPath, png);
  // Pixel statistics of the screenshot, decoded by the browser itself.
  const stats = await page.evaluate(async (data) => {
    const image = new Image();
    image.src = 'data:image/png;base64,' + data;
    await image.decode();
    const canvas = document.createElement('canvas');
    canvas.width = image.width, canvas.height = image.height;
    const context = canvas.getContext('2d');
    context.drawImage(image, 0, 0);
    const pixels = context.getImageData(0, 0, image.width, image.height - 64).data;  // above the control bar
    let differ = 0, blue = 0;
    for (let i = 0; i < pixels.length; i += 4) {
      const r = pixels[i], g = pixels[i + 1], b = pixels[i + 2];
      if (Math.abs(r - 0xf4) + Math.abs(g - 0xf3) + Math.abs(b - 0xf0) > 40) ++differ;
      if (b > r + 40 && b > g + 10) ++blue;
    }
    const total = pixels.length / 4;
    return { differ: differ / total, blue: blue / total };
  }, png.toString('base64'));
  console.log(`  screenshot: ${(100 * stats.differ).toFixed(1)} % of the pixels drawn, ` +
              `${(100 * stats.blue).toFixed(2)} % apparel blue`);
  if (stats.differ < 0.01) failed(`${url}: the screenshot is blank (under 1 % of the pixels differ from the background)`);
  if (options['--apparel'] && stats.blue < 0.0005) failed(`${url}: no apparel tint (blue) in the screenshot`);
  await page.close();
}

let status = 0;
const reports = [];
try {
  for (const [k, url] of urls.entries()) await checkPage(url, k === 0 ? options['--screenshot'] : undefined);
  console.log('check_page: passed');
} catch (error) {
  console.error('check_page: FAILED: ' + error.message);
  status = 1;
} finally {
  await browser.close();
  if (options['--report']) await writeFile(options['--report'], JSON.stringify(reports, null, 1));
}
process.exit(status);
