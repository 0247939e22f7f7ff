// Opens an isotopo HTML report in headless Chromium (Debian's, /usr/bin/chromium) and checks
// what a user would: no script error, nothing fetched from the network, the handle count shown
// equals `analyze --json`'s (or the simplify report's), the tau slider's counts are those of the
// report's sizes, clicking the smallest handle shows its close-up: non-blank WebGL views (both,
// for simplify) with its loops. Exits non-zero on the first failure.
//
//   node report.test.mjs REPORT.html EXPECTED_HANDLES [--screenshot OUT.png]
import { chromium } from 'playwright-core';
import { pathToFileURL } from 'node:url';
import path from 'node:path';
import fs from 'node:fs';
import zlib from 'node:zlib';

const [report, expected, ...rest] = process.argv.slice(2);
const shotAt = rest.indexOf('--screenshot');
const screenshot = shotAt >= 0 ? rest[shotAt + 1] : null;
const url = pathToFileURL(path.resolve(report)).href;

// The report's data read here too, independently of the page: the counts it must show.
const html = fs.readFileSync(report, 'utf8');
const packed = html.match(/id="report-data">([^<]*)<\/script>/)[1].trim();
const data = JSON.parse(zlib.gunzipSync(Buffer.from(packed, 'base64')).toString());
const goingAt = tau => data.handles.filter(h => h.size != null && h.size < tau).length;

function check(ok, what) {
  if (!ok) throw new Error(`FAIL: ${what}`);
  console.log(`  ok: ${what}`);
}

/// Pixels of a canvas as the screen shows them: a screenshot, decoded by the page itself.
async function pixelsOf(page, id) {
  const shot = await page.locator('#' + id).screenshot();
  return page.evaluate(async b64 => {
    const img = new Image();
    img.src = 'data:image/png;base64,' + b64;
    await img.decode();
    const c = document.createElement('canvas');
    c.width = img.width;
    c.height = img.height;
    const ctx = c.getContext('2d');
    ctx.drawImage(img, 0, 0);
    const d = ctx.getImageData(0, 0, c.width, c.height).data;
    let surface = 0, blue = 0, red = 0;
    for (let i = 0; i < d.length; i += 4) {
      const [r, g, b] = [d[i], d[i + 1], d[i + 2]];
      if (Math.abs(r - 0xf0) + Math.abs(g - 0xf2) + Math.abs(b - 0xf5) > 24) surface++;
      if (b > 150 && r < 100) blue++;
      if (r > 150 && g < 80 && b < 80) red++;
    }
    return { all: d.length / 4, surface, blue, red };
  }, shot.toString('base64'));
}

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
  // WebGL in software (SwiftShader): there is no GPU in CI. No background connections: the
  // machine has no network and the test is that the page asks for nothing.
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    '--disable-background-networking', '--disable-component-update', '--disable-sync',
    '--no-first-run', '--disable-quic'],
});
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 900 } });
  const errors = [];
  const fetched = [];
  const local = u => u === url || u.startsWith('blob:') || u.startsWith('data:');
  page.on('pageerror', e => errors.push(String(e)));
  page.on('console', m => { if (m.type() === 'error') errors.push(m.text()); });
  await page.route('**/*', route => {
    const u = route.request().url();
    if (local(u)) return route.continue();
    fetched.push(u);
    return route.abort();
  });
  page.on('request', r => { if (!local(r.url()) && !fetched.includes(r.url())) fetched.push(r.url()); });

  console.log(`report ${report}`);
  await page.goto(url);
  await page.waitForFunction(
    () => document.body.dataset.ready === '1' || !document.getElementById('error').hidden,
    null, { timeout: 120_000 });
  check(await page.isHidden('#error'), `the report loads (${await page.textContent('#error')})`);
  check(errors.length === 0, `no script error (${errors.join('; ')})`);

  const count = await page.textContent('#handle-count');
  check(count === String(expected),
    `handle count shown ${count} = ${expected} (analyze --json's, or the simplify report's)`);

  const counts = async () =>
    [await page.textContent('#count-go'), await page.textContent('#count-stay')].map(Number);
  const max = await page.getAttribute('#tau', 'max');
  const seen = [];
  for (const position of ['0', max]) {
    await page.locator('#tau').fill(position);
    const tau = Number(await page.textContent('#tau-value'));
    const [go, stay] = await counts();
    seen.push(go);
    check(go === goingAt(tau) && go + stay === data.handles.length,
      `slider at tau ${tau}: ${go} go and ${stay} stay, as the report's sizes say`);
  }
  check(seen[0] !== seen[1], `moving the slider changes the counts (${seen[0]}, then ${seen[1]} go)`);
  // Back to tau 20, or the slider's end (the screenshots show it).
  await page.evaluate(() => {
    const s = document.getElementById('tau');
    s.value = String(Math.min(sliderAt(20), SLIDER));
    s.dispatchEvent(new Event('input'));
  });

  // The first row of the table, sorted by size: the smallest handle.
  await page.click('#handles tbody tr');
  await page.waitForTimeout(500);
  const caption = await page.textContent('#view-caption');
  check(/^Handle \d+/.test(caption), `clicking a row shows it in 3D ("${caption.slice(0, 60)}…")`);
  check(!caption.includes('no close-up') && await page.evaluate(() => state.current.bricks != null),
    'the smallest handle has its close-up (not the coarse overview)');
  if (screenshot) {
    // The summary, the plots and the 3D view (the table starts below).
    await page.setViewportSize({ width: 1280, height: 1720 });
    await page.evaluate(() => window.scrollTo(0, 0));
    await page.waitForTimeout(500);
    await page.screenshot({ path: screenshot });
    console.log(`  screenshot ${screenshot}`);
  }
  const views = data.kind === 'simplify' ? ['view-before', 'view-after'] : ['view-before'];
  for (const view of views) {
    const p = await pixelsOf(page, view);
    check(p.surface > p.all * 0.02 && p.surface < p.all * 0.98,
      `${view} shows a surface, neither blank nor filled (${p.surface} of ${p.all} pixels)`);
    check(p.blue + p.red > 20, `${view} shows the loops (${p.blue} blue, ${p.red} red pixels)`);
  }
  check(errors.length === 0, `still no script error (${errors.join('; ')})`);
  check(fetched.length === 0, `nothing fetched from the network (${fetched.join(', ')})`);
} finally {
  await browser.close();
}
