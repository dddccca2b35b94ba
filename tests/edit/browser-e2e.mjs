// Edit.BrowserEndToEnd: `splatwarp edit` on 127.0.0.1 (port 0) driven in Debian's headless
// Chromium (software GL) by puppeteer-core, through the page's own UI: a sphere and a brush
// selection checked against the geometry, then box-select the stripes' ends (shift-drag), make them a fixed and a moving handle, turn the moving one with the keys and
// drag it with the gizmo, undo and redo, scale it, wait for the live Stage I update, key frames 0 and 23,
// scrub, save the animation, refine, save; then `splatwarp deform` with the saved spec must
// give byte-identical baseline.ply and deformed.ply. Exit 77 (skip) without chromium or node_modules.
// Usage: node browser-e2e.mjs SPLATWARP_BINARY [SCREENSHOT.png]
import { spawn, spawnSync } from 'node:child_process';
import { existsSync, mkdtempSync, readFileSync, rmSync, copyFileSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import path from 'node:path';

const CHROMIUM = '/usr/bin/chromium';
const FLAGS = ['--nodes', '64', '--cells', '16', '--iterations', '6', '--eval-points', '5000'];
const [binary, screenshotCopy] = process.argv.slice(2);

function skip(why) {
    console.log(`Edit.BrowserEndToEnd: skipped: ${why}`);
    process.exit(77);
}

function check(ok, what) {
    if (!ok) throw new Error(`check failed: ${what}`);
    console.log(`ok: ${what}`);
}

/** Start `splatwarp edit`; resolves with the process and the URL it prints first. */
function startEditor(model, outDir) {
    const child = spawn(binary, ['-q', 'edit', model, '-o', outDir, '--no-open', ...FLAGS], { stdio: ['ignore', 'pipe', 'inherit'] });
    return new Promise((resolve, reject) => {
        let out = '';
        child.stdout.on('data', (d) => {
            out += d;
            const line = out.split('\n')[0];
            if (out.includes('\n')) resolve({ child, url: line.trim() });
        });
        child.on('exit', (code) => reject(new Error(`splatwarp edit exited with ${code} before printing its URL`)));
    });
}

/** Shift-drag a box around the screen projection of a world box (the page's UI selection). */
async function boxSelect(page, lo, hi) {
    const corners = [];
    for (const x of [lo[0], hi[0]]) for (const y of [lo[1], hi[1]]) for (const z of [lo[2], hi[2]]) corners.push([x, y, z]);
    const screen = await page.evaluate((cs) => cs.map((c) => window.splatwarpEditor.worldToScreen(c)), corners);
    const canvas = await page.evaluate(() => { const r = document.getElementById('canvas').getBoundingClientRect(); return [r.left, r.top]; });
    const xs = screen.map((s) => s[0]), ys = screen.map((s) => s[1]);
    const [x0, y0, x1, y1] = [Math.min(...xs) - 4, Math.min(...ys) - 4, Math.max(...xs) + 4, Math.max(...ys) + 4];
    await page.keyboard.down('Shift');
    await page.mouse.move(canvas[0] + x0, canvas[1] + y0);
    await page.mouse.down();
    await page.mouse.move(canvas[0] + x1, canvas[1] + y1, { steps: 5 });
    await page.mouse.up();
    await page.keyboard.up('Shift');
}

/**
 * Two renderers, one picture: the page's PlayCanvas canvas of the rest model against
 * `splatwarp render` of the same model from the same camera (a graphdeco cameras.json written from
 * the page's camera: OpenCV axes right, down, forward; fx = fy from the vertical fov).
 */
async function crossCheck(page, dir) {
    await new Promise((r) => setTimeout(r, 1500)); // the splat sort runs in a worker: let it settle
    const cam = await page.evaluate(() => window.splatwarpEditor.camera());
    const f = cam.height / 2 / Math.tan((cam.fov * Math.PI) / 360);
    const rotation = [0, 1, 2].map((r) => [cam.right[r], -cam.up[r], cam.forward[r]]);
    writeFileSync(`${dir}/cameras.json`, JSON.stringify([{ id: 0, img_name: 'page', width: cam.width, height: cam.height,
        position: cam.position, rotation, fx: f, fy: f }]));
    const png = await page.evaluate(() => window.splatwarpEditor.canvasPng());
    writeFileSync(`${dir}/page.png`, Buffer.from(png.split(',')[1], 'base64'));
    const render = spawnSync(binary, ['-q', 'render', `${dir}/in.ply`, '--camera', `${dir}/cameras.json`, '-o', `${dir}/ours.png`,
        '--background', '0.12,0.12,0.14', '--device', 'cpu'], { encoding: 'utf8' });
    check(render.status === 0, `splatwarp render from the page's camera ${render.stderr || ''}`);
    const cmp = spawnSync(binary, ['compare', `${dir}/page.png`, `${dir}/ours.png`, '--json'], { encoding: 'utf8' });
    const { psnr, ssim } = JSON.parse(cmp.stdout);
    console.log(`cross-check: PlayCanvas canvas vs splatwarp render, ${cam.width}x${cam.height}: PSNR ${psnr.toFixed(2)} dB, SSIM ${ssim.toFixed(4)}`);
    check(psnr >= 30, `the two renderers agree (PSNR ${psnr.toFixed(2)} dB >= 30)`);
}

/** Canvas offset in the page. */
async function canvasAt(page) {
    return page.evaluate(() => { const r = document.getElementById('canvas').getBoundingClientRect(); return [r.left, r.top]; });
}

/** Shift-drag from one canvas point to another (the page's selection gesture). */
async function shiftDrag(page, from, to, steps) {
    const c = await canvasAt(page);
    await page.keyboard.down('Shift');
    await page.mouse.move(c[0] + from[0], c[1] + from[1]);
    await page.mouse.down();
    await page.mouse.move(c[0] + to[0], c[1] + to[1], { steps });
    await page.mouse.up();
    await page.keyboard.up('Shift');
}

const dist = (a, b) => Math.hypot(...a.map((v, i) => v - b[i]));

/** Sphere (S) and brush (P) selection, checked against the geometry computed here. */
async function sphereAndBrush(page) {
    const points = await page.evaluate(() => window.splatwarpEditor.shownPoints());
    const screen = await page.evaluate((ps) => ps.map((p) => window.splatwarpEditor.worldToScreen(p)), points.gaussians);
    const { min, max } = await page.evaluate(() => window.splatwarpEditor.bbox());
    const mid = min.map((v, a) => (v + max[a]) / 2);
    let near = 0; // the Gaussian nearest the box's middle: press there
    points.gaussians.forEach((p, i) => { if (dist(p, mid) < dist(points.gaussians[near], mid)) near = i; });
    const press = screen[near];
    await page.keyboard.press('s');
    await shiftDrag(page, press, [press[0] + 70, press[1]], 6);
    const sphere = await page.evaluate(() => window.splatwarpEditor.selection);
    check(sphere && sphere.sphere && sphere.sphere.radius > 0, 'a sphere selection was made');
    const { centre, radius } = sphere.sphere;
    const centreAt = await page.evaluate((p) => window.splatwarpEditor.worldToScreen(p), centre);
    check(dist(centreAt, press) <= 12.01, `its centre is a Gaussian under the pointer (${dist(centreAt, press).toFixed(1)} px away)`);
    const within = (list) => list.map((p, i) => [i, dist(p, centre)]).filter(([, d]) => d <= radius).map(([i]) => i);
    const same = (got, want, all) => { // equal sets, but for points on the rim (rounding)
        const g = new Set(got), w = new Set(want);
        return [...g, ...w].every((i) => g.has(i) === w.has(i) || Math.abs(dist(all[i], centre) - radius) < 1e-5 * radius);
    };
    check(same(sphere.gaussians, within(points.gaussians), points.gaussians) && same(sphere.nodes, within(points.nodes), points.nodes),
        `the sphere (r ${radius.toFixed(3)}) selects exactly the Gaussians and nodes within it (${sphere.gaussians.length} and ${sphere.nodes.length})`);
    check(sphere.nodes.length > 0 && sphere.gaussians.length < points.gaussians.length, 'a part, with graph nodes');

    await page.keyboard.press('p');
    await page.$eval('#brushRadius', (el) => { el.value = '20'; });
    const from = [press[0] - 60, press[1]], to = [press[0] + 60, press[1]];
    await shiftDrag(page, from, to, 10);
    const brush = await page.evaluate(() => window.splatwarpEditor.selection);
    const toSegment = (q) => { // distance in pixels from the stroke from -> to
        const t = Math.max(0, Math.min(1, (q[0] - from[0]) / (to[0] - from[0])));
        return Math.hypot(q[0] - (from[0] + t * (to[0] - from[0])), q[1] - from[1]);
    };
    check(brush && brush.gaussians.length > 0 && brush.gaussians.every((i) => screen[i] && toSegment(screen[i]) <= 20.01),
        `the brush selects only what lies under its stroke (${brush ? brush.gaussians.length : 0} Gaussians)`);
    const underPress = screen.findIndex((q) => q && dist(q, from) < 10);
    check(underPress < 0 || brush.gaussians.includes(underPress), 'and what was under the pointer where it started');
    await page.keyboard.press('b');
}

/** Drag the gizmo's x handle (the gizmo sits at the handle's pivot + translate) 40 pixels right. */
async function gizmoDrag(page, handle) {
    const at = handle.pivot.map((v, a) => v + handle.translate[a]);
    const s = await page.evaluate((p) => window.splatwarpEditor.worldToScreen(p), at);
    const canvas = await page.evaluate(() => { const r = document.getElementById('canvas').getBoundingClientRect(); return [r.left, r.top]; });
    const before = await page.evaluate(() => window.splatwarpEditor.poses);
    await page.mouse.move(canvas[0] + s[0] + 55, canvas[1] + s[1]);
    await page.mouse.down();
    await page.mouse.move(canvas[0] + s[0] + 95, canvas[1] + s[1], { steps: 8 });
    await page.mouse.up();
    await waitIdle(page, before);
}

async function waitIdle(page, posesBefore) {
    await page.waitForFunction((n) => window.splatwarpEditor.poses > n && !window.splatwarpEditor.busy, { timeout: 60000 }, posesBefore);
}

/** The page's part: select, pose, refine, save, screenshot. */
async function drive(page, url, shot, dir) {
    const errors = [];
    page.on('pageerror', (e) => errors.push(String(e)));
    page.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
    await page.goto(url);
    await page.waitForFunction(() => window.splatwarpEditor && window.splatwarpEditor.ready, { timeout: 60000 });
    await crossCheck(page, dir);
    await sphereAndBrush(page);
    const { min, max } = await page.evaluate(() => window.splatwarpEditor.bbox());
    const ext = max.map((v, a) => v - min[a]);
    await boxSelect(page, min, [min[0] + 0.08 * ext[0], max[1], max[2]]);
    await page.click('#addFixed');
    await waitIdle(page, 0);
    await boxSelect(page, [max[0] - 0.08 * ext[0], min[1], min[2]], max);
    await page.click('#addMoving');
    await waitIdle(page, 1);
    check(await page.evaluate(() => window.splatwarpEditor.handles) === 2, 'two handles from two box selections');
    await page.$eval('#keyFrame', (el) => { el.value = '0'; });
    await page.click('#addKey'); // frame 0: the rest pose
    await page.keyboard.press('r'); // the scale gizmo (local axes: turn the handle after): its x box, dragged out
    await gizmoDrag(page, (await page.evaluate(() => window.splatwarpEditor.spec())).handles[1]);
    await page.keyboard.press('w');
    const scaled = (await page.evaluate(() => window.splatwarpEditor.spec())).handles[1].scale;
    check(scaled > 1.01, `the scale gizmo scaled the handle (${scaled})`);
    const before = await page.evaluate(() => window.splatwarpEditor.poses);
    for (let i = 0; i < 6; ++i) await page.keyboard.press(']');      // turn the +x end 30 degrees about z
    for (let i = 0; i < 5; ++i) await page.keyboard.press('ArrowUp'); // and lift it by 10% of the diagonal
    await waitIdle(page, before);
    const spec = await page.evaluate(() => window.splatwarpEditor.spec());
    check(spec.handles[1].rotate && Math.abs(spec.handles[1].rotate.degrees - 30) < 1e-6, 'the keys turned the moving handle 30 degrees');
    await gizmoDrag(page, spec.handles[1]);
    const dragged = await page.evaluate(() => window.splatwarpEditor.spec());
    check(dragged.handles[1].translate[0] > spec.handles[1].translate[0] + 0.01, `the gizmo's x arrow moved the handle (x ${dragged.handles[1].translate[0]})`);
    await page.keyboard.down('Control');
    await page.keyboard.press('z');
    await page.keyboard.up('Control');
    await page.waitForFunction(() => !window.splatwarpEditor.busy, { timeout: 60000 });
    check(JSON.stringify(await page.evaluate(() => window.splatwarpEditor.spec())) === JSON.stringify(spec), 'ctrl-Z undid the drag');
    await page.keyboard.down('Control');
    await page.keyboard.press('y');
    await page.keyboard.up('Control');
    await page.waitForFunction(() => !window.splatwarpEditor.busy, { timeout: 60000 });
    check(JSON.stringify(await page.evaluate(() => window.splatwarpEditor.spec())) === JSON.stringify(dragged), 'ctrl-Y redid it');

    await page.$eval('#keyFrame', (el) => { el.value = '23'; });
    await page.click('#addKey'); // frame 23: this pose
    const beforeScrub = await page.evaluate(() => window.splatwarpEditor.poses);
    await page.$eval('#scrub', (el) => { el.value = '12'; el.dispatchEvent(new Event('input')); });
    await waitIdle(page, beforeScrub);
    await page.$eval('#saveName', (el) => { el.value = 'e2e-anim'; });
    await page.click('#saveAnim');
    await page.waitForFunction(() => window.splatwarpEditor.lastAnimation, { timeout: 60000 });
    check(!(await page.evaluate(() => window.splatwarpEditor.lastAnimation)).error, 'keys at 0 and 23, scrubbed to 12, animation saved');
    // The scrub posed frame 12; refine and save the spec's own pose again.
    const beforeRepose = await page.evaluate(() => window.splatwarpEditor.poses);
    await page.keyboard.press('ArrowUp');
    await page.keyboard.press('ArrowDown');
    await waitIdle(page, beforeRepose);
    await page.click('#refine');
    await page.waitForFunction(() => window.splatwarpEditor.progress.state !== 'running' && window.splatwarpEditor.progress.state !== 'idle', { timeout: 120000 });
    check(await page.evaluate(() => window.splatwarpEditor.progress.state) === 'done', 'refine finished');
    await page.$eval('#saveName', (el) => { el.value = 'e2e'; });
    await page.waitForFunction(() => !document.querySelector('#save').disabled, { timeout: 60000 });
    await page.click('#save');
    await page.waitForFunction(() => window.splatwarpEditor.lastSave, { timeout: 60000 });
    const saved = await page.evaluate(() => window.splatwarpEditor.lastSave);
    check(!saved.error, `saved (${JSON.stringify(saved)})`);
    await page.click('#viewStage1'); // the handles' colours and the pose (the README's picture)
    await new Promise((r) => setTimeout(r, 500));
    await page.screenshot({ path: shot });
    const lit = await page.evaluate(() => window.splatwarpEditor.litPixels());
    check(lit > 2000, `the canvas shows the splats (${lit} pixels differ from the background)`);
    check(errors.length === 0, `no page errors (${errors.join(' | ')})`);
}

async function main() {
    if (!binary) throw new Error('usage: node browser-e2e.mjs SPLATWARP_BINARY [SCREENSHOT.png]');
    if (!existsSync(CHROMIUM)) skip(`${CHROMIUM} not installed`);
    let puppeteer;
    try { puppeteer = (await import('puppeteer-core')).default; } catch (e) { skip('node_modules/puppeteer-core missing (scripts/setup.sh runs npm ci)'); }
    const dir = mkdtempSync(path.join(tmpdir(), 'splatwarp-edit-e2e-'));
    const run = (args) => spawnSync(binary, args, { encoding: 'utf8' });
    let editor, browser;
    try {
        check(run(['-q', 'sample', 'stripes', '--count', '2000', '-o', `${dir}/in.ply`]).status === 0, 'sample stripes');
        editor = await startEditor(`${dir}/in.ply`, `${dir}/edits`);
        check(/^http:\/\/127\.0\.0\.1:\d+\/\?token=[0-9a-f]{32}$/.test(editor.url), `edit printed ${editor.url}`);
        browser = await puppeteer.launch({
            executablePath: CHROMIUM, headless: true, defaultViewport: { width: 1200, height: 720 },
            args: ['--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--no-sandbox', '--disable-background-networking',
                '--disable-component-update', '--disable-sync', '--no-first-run', '--disable-quic', `--user-data-dir=${dir}/profile`]
        });
        await drive(await browser.newPage(), editor.url, `${dir}/editor.png`, dir);
        if (screenshotCopy) copyFileSync(`${dir}/editor.png`, screenshotCopy);
        await browser.close();
        browser = null;
        editor.child.kill('SIGINT');
        const code = await new Promise((r) => editor.child.on('exit', r));
        check(code === 0, `splatwarp edit stopped cleanly on SIGINT (exit ${code})`);
        const replay = run(['-q', 'deform', `${dir}/in.ply`, '--spec', `${dir}/edits/e2e/spec.json`, '-o', `${dir}/cli`, ...FLAGS]);
        check(replay.status === 0, `deform replays the saved spec ${replay.stderr || ''}`);
        for (const f of ['baseline.ply', 'deformed.ply'])
            check(readFileSync(`${dir}/edits/e2e/${f}`).equals(readFileSync(`${dir}/cli/${f}`)), `${f}: the editor's bytes equal deform's`);
        const anim = run(['-q', 'animate', `${dir}/in.ply`, '--spec', `${dir}/edits/e2e-anim/animation.json`, '-o', `${dir}/anim`, '--specs-only', ...FLAGS]);
        check(anim.status === 0, `animate reads the saved animation ${anim.stderr || ''}`);
        const frame23 = JSON.parse(readFileSync(`${dir}/anim/specs/spec.0023.json`, 'utf8'));
        const turned = frame23.handles[1].rotate.degrees;
        check(Math.abs(turned - 30) < 1e-9, `its frame 23 is the keyed pose (30 degrees: ${turned})`);
        console.log('1 passed, 0 failed');
    } finally {
        if (browser) await browser.close().catch(() => {});
        if (editor && editor.child.exitCode === null) editor.child.kill('SIGINT');
        if (process.env.KEEP_E2E) console.log(`kept ${dir}`); else rmSync(dir, { recursive: true, force: true });
    }
}

const guard = setTimeout(() => { console.error('Edit.BrowserEndToEnd: timed out after 240 s'); process.exit(1); }, 240000);
main().then(() => { clearTimeout(guard); process.exit(0); }, (e) => { console.error(`Edit.BrowserEndToEnd: ${e.stack || e}`); console.log('0 passed, 1 failed'); process.exit(1); });
