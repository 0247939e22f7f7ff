// Opens an isotopo HTML report in headless Chromium (Debian's, /usr/bin/chromium) and checks
// what a user would: no script error, nothing fetched from the network, the handle count shown
// equals `analyze --json`'s, the tau slider changes the counts shown, clicking a handle renders
// a non-blank WebGL view with its loops. Exits non-zero on the first failure.
//
//   node report.test.mjs REPORT.html EXPECTED_HANDLES [--screenshot OUT.png]
import { chromium } from 'playwright-core';
import { pathToFileURL } from 'node:url';
import path from 'node:path';

const [report, expected, ...rest] = process.argv.slice(2);
const shotAt = rest.indexOf('--screenshot');
const screenshot = shotAt >= 0 ? rest[shotAt + 1] : null;
const url = pathToFileURL(path.resolve(report)).href;

function check(ok, what) {
  if (!ok) throw new Error(`FAIL: ${what}`);
  console.log(`  ok: ${what}`);
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
  page.on('pageerror', e => errors.push(String(e)));
  page.on('console', m => { if (m.type() === 'error') errors.push(m.text()); });
  await page.route('**/*', route => {
    const u = route.request().url();
    if (u === url || u.startsWith('blob:') || u.startsWith('data:')) return route.continue();
    fetched.push(u);
    return route.abort();
  });
  page.on('request', r => {
    const u = r.url();
    if (u !== url && !u.startsWith('blob:') && !u.startsWith('data:') && !fetched.includes(u)) fetched.push(u);
  });
  console.log(`report ${report}`);
  await page.goto(url);
  await page.waitForFunction(() => document.body.dataset.ready === '1' || !document.getElementById('error').hidden, null, { timeout: 120_000 });
  check(await page.isHidden('#error'), 'the report loads (' + await page.textContent('#error') + ')');
  check(errors.length === 0, `no script error (${errors.join('; ')})`);

  const count = await page.textContent('#handle-count');
  check(count === String(expected), `handle count shown ${count} = ${expected} (analyze --json's, or the simplify report's)`);

  const counts = async () => [await page.textContent('#count-go'), await page.textContent('#count-stay')];
  const max = await page.getAttribute('#tau', 'max');
  await page.locator('#tau').fill('0');
  const low = await counts();
  const tauLow = await page.textContent('#tau-value');
  await page.locator('#tau').fill(max);
  const high = await counts();
  const tauHigh = await page.textContent('#tau-value');
  check(low[0] !== high[0] && Number(low[0]) + Number(low[1]) === Number(expected),
    `moving the slider changes the counts (tau ${tauLow}: ${low[0]} go; tau ${tauHigh}: ${high[0]} go)`);
  check(Number(high[1]) === 0 || (await page.evaluate(() => state.data.handles.some(h => h.size === Infinity))),
    `at the largest tau every measured handle goes (${high[1]} stay)`);
  // Back to tau 20 (the screenshots show it).
  await page.evaluate(() => {
    const s = document.getElementById('tau');
    s.value = String(sliderAt(20));
    s.dispatchEvent(new Event('input'));
  });

  // The first row of the table, sorted by size: the smallest handle.
  await page.click('#handles tbody tr');
  await page.waitForTimeout(500);
  const caption = await page.textContent('#view-caption');
  check(/^Handle \d+/.test(caption), `clicking a row shows it in 3D ("${caption.slice(0, 60)}…")`);
  if (screenshot) {
    // The summary, the plots and the 3D view (the table starts below).
    await page.setViewportSize({ width: 1280, height: 1720 });
    await page.evaluate(() => window.scrollTo(0, 0));
    await page.waitForTimeout(500);
    await page.screenshot({ path: screenshot });
    console.log(`  screenshot ${screenshot}`);
  }
  // The view as the screen shows it: a screenshot of its canvas, its pixels counted (the
  // PNG decoded by the page itself; nothing else needed).
  const shot = await page.locator('#view-before').screenshot();
  const pixels = await page.evaluate(async b64 => {
    const img = new Image();
    img.src = 'data:image/png;base64,' + b64;
    await img.decode();
    const c = document.createElement('canvas');
    c.width = img.width; c.height = img.height;
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
  check(pixels.surface > pixels.all * 0.02,
    `the 3D view is not blank (${pixels.surface} of ${pixels.all} pixels drawn)`);
  check(pixels.blue + pixels.red > 20, `its loops are drawn (${pixels.blue} blue, ${pixels.red} red pixels)`);
  check(errors.length === 0, `still no script error (${errors.join('; ')})`);
  check(fetched.length === 0, `nothing fetched from the network (${fetched.join(', ')})`);
} finally {
  await browser.close();
}
