// splatwarp edit: the page. Renders the model with PlayCanvas (served by our server from
// node_modules), lets the user box-select handles, move them with a gizmo or keys, and drives the
// HTTP API (docs/editor-api.md): every change POSTs the whole spec to /api/pose and shows the
// Stage I Gaussians it returns; Refine, Cancel, Save; undo/redo of poses.
const token = new URL(import.meta.url).searchParams.get('token');
const pc = await import(`./playcanvas.mjs?token=${encodeURIComponent(token)}`);

const SH_C0 = 0.28209479177387814;
const $ = (id) => document.getElementById(id);

/** fetch with the run's token; throws with the server's message unless the status is 2xx. */
async function api(path, options = {}) {
    const headers = { ...(options.headers || {}), Authorization: `Bearer ${token}` };
    const res = await fetch(path, { ...options, headers });
    if (!res.ok) {
        let message = `${res.status}`;
        try { message = (await res.json()).error || message; } catch (e) { /* not JSON */ }
        throw new Error(`${path}: ${message}`);
    }
    return res;
}

/**
 * The SWG1 layout (docs/editor-api.md): header, then means, rotations (w,x,y,z), log scales and,
 * in a model (14 floats per Gaussian), opacity logits and SH DC; a pose (10) takes those from `rest`.
 */
function decodeModel(buffer, rest = null) {
    const view = new DataView(buffer);
    const magic = String.fromCharCode(view.getUint8(0), view.getUint8(1), view.getUint8(2), view.getUint8(3));
    if (magic !== 'SWG1') throw new Error('not an SWG1 model');
    const n = view.getUint32(4, true), floats = view.getUint32(8, true);
    if (floats !== 14 && floats !== 10) throw new Error(`SWG1 with ${floats} floats per Gaussian`);
    if (floats === 10 && (!rest || rest.n !== n)) throw new Error('an SWG1 pose needs its rest model');
    const f = new Float32Array(buffer, 16, n * floats);
    return {
        n,
        means: f.subarray(0, 3 * n), rotations: f.subarray(3 * n, 7 * n), logScales: f.subarray(7 * n, 10 * n),
        opacities: floats === 14 ? f.subarray(10 * n, 11 * n) : rest.opacities,
        dc: floats === 14 ? f.subarray(11 * n, 14 * n) : rest.dc
    };
}

// ---- the splats: one GSplatContainer whose textures are rewritten on every pose ----

const HANDLE_COLORS = [[1.0, 0.6, 0.15], [0.25, 0.65, 1.0]]; // moving, fixed

class SplatView {
    constructor(app, entity) {
        this.app = app;
        this.entity = entity;
        this.container = null;
    }

    ensureCapacity(n) {
        if (this.container && this.container.maxSplats >= n) return;
        const format = pc.GSplatFormat.createDefaultFormat(this.app.graphicsDevice);
        const old = this.container;
        this.container = new pc.GSplatContainer(this.app.graphicsDevice, n, format);
        if (this.entity.gsplat) this.entity.gsplat.resource = this.container;
        else this.entity.addComponent('gsplat', { resource: this.container });
        // Centres change every pose: the work buffer is rebuilt each frame.
        this.entity.gsplat.workBufferUpdate = pc.WORKBUFFER_UPDATE_ALWAYS;
        if (old) old.destroy();
    }

    /** Show a decoded model; tint[i] = 0 none, 1 moving handle, 2 fixed handle, 3 selection. */
    show(model, tint) {
        this.ensureCapacity(model.n);
        const c = this.container, n = model.n, half = pc.FloatPacking.float2Half;
        const center = c.getTexture('dataCenter').lock(), color = c.getTexture('dataColor').lock();
        const scale = c.getTexture('dataScale').lock(), rot = c.getTexture('dataRotation').lock();
        const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
        for (let i = 0; i < n; ++i) {
            for (let a = 0; a < 3; ++a) {
                const p = model.means[3 * i + a];
                center[4 * i + a] = p;
                lo[a] = Math.min(lo[a], p); hi[a] = Math.max(hi[a], p);
                scale[4 * i + a] = half(Math.exp(model.logScales[3 * i + a]));
            }
            const w = model.rotations[4 * i], x = model.rotations[4 * i + 1], y = model.rotations[4 * i + 2], z = model.rotations[4 * i + 3];
            const len = Math.hypot(w, x, y, z) || 1;
            // (w, x, y, z): the default format's getRotation() is read as w,x,y,z by the splat shader
            // (it swizzles .yzwx into x,y,z,w), whatever its d.ts says; tests/edit's cross-check shows it.
            rot[4 * i] = half(w / len); rot[4 * i + 1] = half(x / len); rot[4 * i + 2] = half(y / len); rot[4 * i + 3] = half(z / len);
            const t = tint ? tint[i] : 0;
            for (let a = 0; a < 3; ++a) {
                let v = 0.5 + SH_C0 * model.dc[3 * i + a];
                if (t) v = 0.35 * v + 0.65 * (t === 3 ? [1, 1, 0.2][a] : HANDLE_COLORS[t - 1][a]);
                color[4 * i + a] = half(v);
            }
            color[4 * i + 3] = half(1 / (1 + Math.exp(-model.opacities[i])));
        }
        for (const name of ['dataCenter', 'dataColor', 'dataScale', 'dataRotation']) c.getTexture(name).unlock();
        c.centers.set(model.means);
        c.aabb.setMinMax(new pc.Vec3(...lo), new pc.Vec3(...hi));
        this.entity.gsplat.customAabb = c.aabb.clone();
        c.update(n, true);
    }
}

// ---- the camera: orbit, pan, zoom about a target ----

class Orbit {
    constructor(camera, target, distance) {
        this.camera = camera;
        this.target = target.clone();
        this.distance = distance;
        this.yaw = 0;
        this.pitch = 0;
        this.apply();
    }

    apply() {
        const q = new pc.Quat().setFromEulerAngles(this.pitch, this.yaw, 0);
        const offset = q.transformVector(new pc.Vec3(0, 0, this.distance));
        this.camera.setPosition(this.target.clone().add(offset));
        this.camera.setRotation(q);
    }

    rotate(dx, dy) {
        this.yaw -= dx * 0.3;
        this.pitch = Math.max(-89, Math.min(89, this.pitch - dy * 0.3));
        this.apply();
    }

    pan(dx, dy, height) {
        const perPixel = 2 * this.distance * Math.tan((this.camera.camera.fov * Math.PI) / 360) / height;
        const right = this.camera.right.clone().mulScalar(-dx * perPixel);
        const up = this.camera.up.clone().mulScalar(dy * perPixel);
        this.target.add(right).add(up);
        this.apply();
    }

    zoom(delta) {
        this.distance *= Math.exp(delta * 0.001);
        this.apply();
    }
}

// ---- the editor ----

class Editor {
    constructor() {
        this.canvas = $('canvas');
        this.rest = null;          // decoded rest model
        this.stage1 = null;        // the last pose's Stage I model
        this.refined = null;       // the refined model of the current pose
        this.graph = null;         // GET /api/graph
        this.view = 'stage1';
        this.handles = [];         // {nodes, gaussians, fixed, pivot, translate, quat: [x,y,z,w]}
        this.active = -1;          // the handle the gizmo moves
        this.selection = null;     // {gaussians, nodes} of the last box, sphere or brush stroke
        this.tool = 'box';         // what shift-drag selects with: box, sphere, brush
        this.history = [];
        this.future = [];
        this.poses = 0;            // poses shown (the test hook waits on it)
        this.posing = false;
        this.posePending = false;
        this.progress = { state: 'idle' };
        this.lastSave = null;
        this.lastAnimation = null;
        this.keys = new Map();     // frame -> [per handle: {translate, quat} or null (fixed)]
        this.ready = false;
    }

    async start() {
        this.createApp();
        const [model, graph] = await Promise.all([
            api('/api/model').then((r) => r.arrayBuffer()), api('/api/graph').then((r) => r.json())]);
        this.rest = decodeModel(model);
        this.graph = graph;
        const lo = new pc.Vec3(...graph.bboxMin), hi = new pc.Vec3(...graph.bboxMax);
        this.extent = hi.clone().sub(lo).length() || 1;
        const centre = lo.clone().add(hi).mulScalar(0.5);
        this.orbit = new Orbit(this.cameraEntity, centre, 1.3 * this.extent);
        this.createGizmos();
        this.bindPointer();
        this.bindKeys();
        this.bindButtons();
        this.render();
        $('model').textContent = `${graph.gaussians} Gaussians (SH ${graph.shDegree}), ${graph.nodes.length} graph nodes`;
        this.ready = true;
        this.setStatus('Shift-drag a box over the part to hold, make it a fixed handle; box the part to move, make it a moving handle.');
    }

    createApp() {
        const app = new pc.Application(this.canvas, { graphicsDeviceOptions: { antialias: false, preserveDrawingBuffer: true } });
        app.setCanvasFillMode(pc.FILLMODE_NONE);
        app.setCanvasResolution(pc.RESOLUTION_AUTO);
        const resize = () => app.resizeCanvas(this.canvas.clientWidth, this.canvas.clientHeight);
        window.addEventListener('resize', resize);
        resize();
        this.cameraEntity = new pc.Entity('camera');
        this.cameraEntity.addComponent('camera', { clearColor: new pc.Color(0.12, 0.12, 0.14), fov: 45, nearClip: 0.01, farClip: 1000 });
        app.root.addChild(this.cameraEntity);
        this.splatEntity = new pc.Entity('splats');
        app.root.addChild(this.splatEntity);
        this.splats = new SplatView(app, this.splatEntity);
        this.pivot = new pc.Entity('pivot');
        app.root.addChild(this.pivot);
        app.on('update', () => this.drawNodes());
        app.start();
        this.app = app;
    }

    createGizmos() {
        const layer = pc.Gizmo.createLayer(this.app);
        this.gizmos = {
            translate: new pc.TranslateGizmo(this.cameraEntity.camera, layer),
            rotate: new pc.RotateGizmo(this.cameraEntity.camera, layer),
            scale: new pc.ScaleGizmo(this.cameraEntity.camera, layer)
        };
        this.gizmos.scale.uniform = true; // the spec's scale is uniform (the axes' mean is taken)
        this.mode = 'translate';
        for (const gizmo of Object.values(this.gizmos)) {
            gizmo.size = 1.2;
            gizmo.on('transform:start', () => { this.dragging = true; });
            gizmo.on('transform:move', () => this.followPivot());
            gizmo.on('transform:end', () => { this.dragging = false; this.followPivot(); this.commit(); });
        }
    }

    /** The active handle's motion from the pivot entity the gizmo moved. */
    followPivot() {
        const h = this.handles[this.active];
        if (!h || h.fixed) return;
        // Local = world here (a child of the root); the local values are not rounded through a float32 matrix.
        const p = this.pivot.getLocalPosition(), q = this.pivot.getLocalRotation(), k = this.pivot.getLocalScale();
        h.translate = [p.x - h.pivot[0], p.y - h.pivot[1], p.z - h.pivot[2]];
        h.quat = [q.x, q.y, q.z, q.w];
        if (this.mode === 'scale') h.scale = Math.cbrt(Math.abs(k.x * k.y * k.z)) || 1;
        this.requestPose();
    }

    attachGizmo() {
        for (const gizmo of Object.values(this.gizmos)) gizmo.detach();
        const h = this.handles[this.active];
        if (!h || h.fixed) return;
        this.pivot.setLocalPosition(h.pivot[0] + h.translate[0], h.pivot[1] + h.translate[1], h.pivot[2] + h.translate[2]);
        this.pivot.setLocalRotation(new pc.Quat(h.quat[0], h.quat[1], h.quat[2], h.quat[3]));
        const k = h.scale ?? 1;
        this.pivot.setLocalScale(k, k, k);
        this.gizmos[this.mode].attach([this.pivot]);
    }

    // ---- pointer: orbit, pan, zoom, selection (box, sphere, brush) ----

    bindPointer() {
        let drag = null;
        this.canvas.addEventListener('contextmenu', (e) => e.preventDefault());
        this.canvas.addEventListener('pointerdown', (e) => {
            if (this.dragging) return; // the gizmo has it
            drag = { x: e.offsetX, y: e.offsetY, button: e.button, select: e.shiftKey && e.button === 0 };
            if (drag.select) drag.tool = this.beginSelect(e.offsetX, e.offsetY);
            this.canvas.setPointerCapture(e.pointerId);
        });
        this.canvas.addEventListener('pointermove', (e) => {
            if (!drag || this.dragging) return;
            if (drag.select) { this.moveSelect(drag, e.offsetX, e.offsetY); return; }
            if (drag.button === 0) this.orbit.rotate(e.movementX, e.movementY);
            else this.orbit.pan(e.movementX, e.movementY, this.canvas.clientHeight);
        });
        this.canvas.addEventListener('pointerup', (e) => {
            if (drag && drag.select) this.endSelect(drag, e.offsetX, e.offsetY);
            drag = null;
        });
        this.canvas.addEventListener('wheel', (e) => { e.preventDefault(); this.orbit.zoom(e.deltaY); }, { passive: false });
    }

    /** Screen position (CSS pixels of the canvas) of a world point, or null behind the camera. */
    worldToScreen(p) {
        const s = this.cameraEntity.camera.worldToScreen(new pc.Vec3(p[0], p[1], p[2]), new pc.Vec3());
        return s.z > 0 ? [s.x, s.y] : null; // in the canvas's CSS pixels (its client rect)
    }

    /** The Gaussians selectable where they are shown (a refined model with other Gaussians: where they rest). */
    selectable() {
        return this.shownModel().n === this.rest.n ? this.shownModel() : this.rest;
    }

    /** Screen x, y and distance from the camera (NaN behind it) of every shown Gaussian and graph node, once per selection. */
    project() {
        const shown = this.selectable(), camera = this.cameraEntity.camera, v = new pc.Vec3(), out = new pc.Vec3();
        const eye = this.cameraEntity.getPosition();
        const at = (p, dst, i) => {
            camera.worldToScreen(v.set(p[0], p[1], p[2]), out);
            dst[3 * i] = out.x, dst[3 * i + 1] = out.y, dst[3 * i + 2] = out.z > 0 ? v.distance(eye) : NaN;
        };
        const gaussians = new Float32Array(3 * shown.n), nodes = new Float32Array(3 * this.graph.nodes.length);
        for (let i = 0; i < shown.n; ++i) at([shown.means[3 * i], shown.means[3 * i + 1], shown.means[3 * i + 2]], gaussians, i);
        this.graph.nodes.forEach((p, j) => at(this.nodePosition(j, p), nodes, j));
        return { shown, gaussians, nodes };
    }

    beginSelect(x, y) {
        const tool = { kind: this.tool, projected: this.tool === 'box' ? null : this.project() };
        if (tool.kind === 'sphere') tool.centre = this.pickGaussian(tool.projected, x, y);
        if (tool.kind === 'brush') { tool.gaussians = new Set(); tool.nodes = new Set(); this.paint(tool, x, y); }
        return tool;
    }

    moveSelect(drag, x, y) {
        const t = drag.tool;
        if (t.kind === 'box') {
            this.overlay(Math.min(drag.x, x), Math.min(drag.y, y), Math.abs(x - drag.x), Math.abs(y - drag.y), false);
        } else if (t.kind === 'sphere' && t.centre) {
            t.radius = this.sphereRadius(t.centre, x, y);
            const r = Math.hypot(x - t.centre.screen[0], y - t.centre.screen[1]);
            this.overlay(t.centre.screen[0] - r, t.centre.screen[1] - r, 2 * r, 2 * r, true);
        } else if (t.kind === 'brush') {
            this.paint(t, x, y);
        }
    }

    endSelect(drag, x, y) {
        $('rect').style.display = 'none';
        const t = drag.tool;
        if (t.kind === 'box') return this.selectRect(drag.x, drag.y, x, y);
        if (t.kind === 'sphere') {
            if (!t.centre) return this.setStatus('sphere: press on the model (a Gaussian centre under the pointer) and drag out the radius');
            return this.selectSphere(t.centre.world, this.sphereRadius(t.centre, x, y));
        }
        this.paint(t, x, y);
        this.setSelection([...t.gaussians].sort((a, b) => a - b), [...t.nodes].sort((a, b) => a - b));
    }

    /** The box overlay, or a circle (sphere, brush) in canvas pixels. */
    overlay(left, top, width, height, round) {
        Object.assign($('rect').style, { display: 'block', left: `${left}px`, top: `${top}px`, width: `${width}px`,
            height: `${height}px`, borderRadius: round ? '50%' : '0' });
    }

    /** The nearest-to-the-camera Gaussian whose centre projects within 12 pixels of (x, y). */
    pickGaussian(projected, x, y) {
        let best = -1;
        const g = projected.gaussians;
        for (let i = 0; 3 * i < g.length; ++i) {
            if (!(g[3 * i + 2] > 0) || Math.hypot(g[3 * i] - x, g[3 * i + 1] - y) > 12) continue;
            if (best < 0 || g[3 * i + 2] < g[3 * best + 2]) best = i;
        }
        if (best < 0) return null;
        const m = projected.shown.means;
        return { world: [m[3 * best], m[3 * best + 1], m[3 * best + 2]], screen: [g[3 * best], g[3 * best + 1]], depth: g[3 * best + 2] };
    }

    /** World radius of a sphere about a picked centre whose rim passes under (x, y), at the centre's distance from the camera. */
    sphereRadius(centre, x, y) {
        const rim = this.cameraEntity.camera.screenToWorld(x, y, centre.depth, new pc.Vec3());
        return Math.hypot(rim.x - centre.world[0], rim.y - centre.world[1], rim.z - centre.world[2]);
    }

    /** Brush: add what projects within the brush radius of (x, y). */
    paint(tool, x, y) {
        const r = this.brushRadius, { gaussians, nodes } = tool.projected;
        for (let i = 0; 3 * i < gaussians.length; ++i)
            if (gaussians[3 * i + 2] > 0 && Math.hypot(gaussians[3 * i] - x, gaussians[3 * i + 1] - y) <= r) tool.gaussians.add(i);
        for (let j = 0; 3 * j < nodes.length; ++j)
            if (nodes[3 * j + 2] > 0 && Math.hypot(nodes[3 * j] - x, nodes[3 * j + 1] - y) <= r) tool.nodes.add(j);
        this.overlay(x - r, y - r, 2 * r, 2 * r, true);
    }

    get brushRadius() { return Math.max(2, Number($('brushRadius').value) || 24); }

    /** The Gaussians (shown model) and graph nodes whose centres project into a screen box. */
    selectRect(x0, y0, x1, y1) {
        const [ax, bx] = [Math.min(x0, x1), Math.max(x0, x1)], [ay, by] = [Math.min(y0, y1), Math.max(y0, y1)];
        const inside = (p) => { const s = this.worldToScreen(p); return s && s[0] >= ax && s[0] <= bx && s[1] >= ay && s[1] <= by; };
        const shown = this.selectable();
        const gaussians = [];
        for (let i = 0; i < shown.n; ++i)
            if (inside([shown.means[3 * i], shown.means[3 * i + 1], shown.means[3 * i + 2]])) gaussians.push(i);
        const nodes = [];
        this.graph.nodes.forEach((p, j) => { if (inside(this.nodePosition(j, p))) nodes.push(j); });
        this.setSelection(gaussians, nodes);
    }

    /** The Gaussians (shown model) and graph nodes (where shown) within a world-space sphere. */
    selectSphere(c, r) {
        const shown = this.selectable(), within = (p) => Math.hypot(p[0] - c[0], p[1] - c[1], p[2] - c[2]) <= r;
        const gaussians = [];
        for (let i = 0; i < shown.n; ++i)
            if (within([shown.means[3 * i], shown.means[3 * i + 1], shown.means[3 * i + 2]])) gaussians.push(i);
        const nodes = [];
        this.graph.nodes.forEach((p, j) => { if (within(this.nodePosition(j, p))) nodes.push(j); });
        this.lastSphere = { centre: c, radius: r };
        this.setSelection(gaussians, nodes);
    }

    setSelection(gaussians, nodes) {
        this.selection = nodes.length ? { gaussians, nodes } : null;
        $('selection').textContent = nodes.length ? `${gaussians.length} Gaussians, ${nodes.length} graph nodes`
            : `${gaussians.length} Gaussians but no graph node: select a larger part`;
        $('addFixed').disabled = $('addMoving').disabled = !this.selection;
        this.render();
    }

    setTool(tool) {
        this.tool = tool;
        for (const [id, t] of [['toolBox', 'box'], ['toolSphere', 'sphere'], ['toolBrush', 'brush']]) $(id).classList.toggle('on', t === tool);
    }

    /** A node's shown position: at rest, or moved with its handle's motion (the view follows the pose). */
    nodePosition(j, rest) {
        if (this.view === 'rest') return rest;
        for (let k = this.handles.length - 1; k >= 0; --k) {
            const h = this.handles[k];
            if (!h.fixed && h.nodes.includes(j)) return applyMotion(h, rest);
        }
        return rest;
    }

    shownModel() {
        if (this.view === 'rest' || !this.stage1) return this.rest;
        if (this.view === 'refined' && this.refined) return this.refined;
        return this.stage1;
    }

    // ---- handles, spec, pose ----

    addHandle(fixed) {
        if (!this.selection) return;
        const s = this.selection, c = [0, 0, 0];
        for (const j of s.nodes) for (let a = 0; a < 3; ++a) c[a] += this.graph.nodes[j][a] / s.nodes.length;
        this.handles.push({ nodes: s.nodes, gaussians: s.gaussians, fixed, pivot: c, translate: [0, 0, 0], quat: [0, 0, 0, 1], scale: 1 });
        this.selection = null;
        $('selection').textContent = 'nothing selected';
        $('addFixed').disabled = $('addMoving').disabled = true;
        if (!fixed) this.active = this.handles.length - 1;
        this.commit();
    }

    spec() {
        return {
            version: 1, units: 'world',
            handles: this.handles.map((h) => {
                if (h.fixed) return { nodes: h.nodes, fixed: true };
                return { nodes: h.nodes, pivot: h.pivot, ...motionJson(h.translate, h.quat, h.scale) };
            })
        };
    }

    /** POST the spec; while one is in flight only the newest change waits (a drag sends what it can). */
    async requestPose(request = { path: '/api/pose', spec: () => this.spec() }) {
        if (!this.handles.length) { this.stage1 = null; this.render(); return; }
        this.nextPose = request;
        if (this.posing) { this.posePending = true; return; }
        this.posing = true;
        try {
            const t0 = performance.now();
            const body = JSON.stringify(this.nextPose.spec());
            const res = await api(this.nextPose.path, { method: 'POST', headers: { 'Content-Type': 'application/json' }, body });
            this.stage1 = decodeModel(await res.arrayBuffer(), this.rest);
            this.refined = null;
            $('viewRefined').disabled = true;
            if (this.view === 'refined') this.view = 'stage1';
            const ms = performance.now() - t0;
            this.poses += 1;
            this.setStatus(`pose ${this.poses}: ${res.headers.get('X-Splatwarp-Moving')} Gaussians moved; ED solve ` +
                `${(+res.headers.get('X-Splatwarp-Solve-Ms')).toFixed(1)} ms, Stage I ${(+res.headers.get('X-Splatwarp-Update-Ms')).toFixed(1)} ms, ` +
                `round trip ${ms.toFixed(0)} ms`);
            this.render();
        } catch (e) {
            this.setStatus(String(e.message || e));
        } finally {
            this.posing = false;
            if (this.posePending) { this.posePending = false; this.requestPose(this.nextPose); }
        }
        this.updateButtons();
    }

    // ---- undo / redo: snapshots of the handles, each change one step ----

    snapshot() { return JSON.stringify({ handles: this.handles, active: this.active }); }

    commit() {
        const now = this.snapshot();
        if (this.history[this.history.length - 1] !== now) { this.history.push(now); this.future = []; }
        this.afterChange();
    }

    undo() {
        if (this.history.length < 1) return;
        this.future.push(this.history.pop());
        this.restore(this.history[this.history.length - 1]);
    }

    redo() {
        if (!this.future.length) return;
        const s = this.future.pop();
        this.history.push(s);
        this.restore(s);
    }

    restore(s) {
        const state = s ? JSON.parse(s) : { handles: [], active: -1 };
        this.handles = state.handles;
        this.active = state.active;
        this.afterChange();
    }

    afterChange() {
        this.renderHandles();
        this.attachGizmo();
        this.requestPose();
        this.updateButtons();
    }

    renderHandles() {
        const list = $('handles');
        list.textContent = '';
        this.handles.forEach((h, i) => {
            const row = document.createElement('div');
            row.className = 'handle' + (i === this.active ? ' active' : '');
            const [r, g, b] = HANDLE_COLORS[h.fixed ? 1 : 0];
            row.innerHTML = `<span class="swatch" style="background: rgb(${r * 255},${g * 255},${b * 255})"></span>`;
            row.append(`${i + 1}: ${h.fixed ? 'fixed' : 'moving'}, ${h.nodes.length} nodes `);
            const toggle = document.createElement('button');
            toggle.textContent = h.fixed ? 'make moving' : 'make fixed';
            toggle.onclick = (e) => { e.stopPropagation(); h.fixed = !h.fixed; h.translate = [0, 0, 0]; h.quat = [0, 0, 0, 1]; h.scale = 1; this.commit(); };
            const remove = document.createElement('button');
            remove.textContent = '×';
            remove.onclick = (e) => { e.stopPropagation(); this.handles.splice(i, 1); this.active = -1; this.commit(); };
            row.append(toggle, remove);
            row.onclick = () => { this.active = i; this.renderHandles(); this.attachGizmo(); };
            list.append(row);
        });
    }

    // ---- keys, buttons ----

    /** Move or turn the active moving handle (keys and the test hook). */
    nudge(translate, degreesAboutZ = 0) {
        const h = this.handles[this.active];
        if (!h || h.fixed) return;
        for (let a = 0; a < 3; ++a) h.translate[a] += translate[a];
        if (degreesAboutZ) {
            const q = new pc.Quat().setFromAxisAngle(new pc.Vec3(0, 0, 1), degreesAboutZ);
            const cur = new pc.Quat(h.quat[0], h.quat[1], h.quat[2], h.quat[3]);
            const out = new pc.Quat().mul2(q, cur);
            h.quat = [out.x, out.y, out.z, out.w];
        }
        this.attachGizmo();
        this.commit();
    }

    bindKeys() {
        window.addEventListener('keydown', (e) => {
            if (e.target instanceof HTMLInputElement) return;
            const step = 0.02 * this.extent;
            const moves = { ArrowLeft: [-step, 0, 0], ArrowRight: [step, 0, 0], ArrowUp: [0, step, 0], ArrowDown: [0, -step, 0], PageUp: [0, 0, step], PageDown: [0, 0, -step] };
            if ((e.ctrlKey || e.metaKey) && e.key.toLowerCase() === 'z') { this.undo(); e.preventDefault(); return; }
            if ((e.ctrlKey || e.metaKey) && e.key.toLowerCase() === 'y') { this.redo(); e.preventDefault(); return; }
            if (moves[e.key]) { this.nudge(moves[e.key]); e.preventDefault(); }
            else if (e.key === '[' || e.key === ']') this.nudge([0, 0, 0], e.key === ']' ? 5 : -5);
            else if (e.key === 'w' || e.key === 'W') this.setMode('translate');
            else if (e.key === 'e' || e.key === 'E') this.setMode('rotate');
            else if (e.key === 'r' || e.key === 'R') this.setMode('scale');
            else if (e.key === 'b' || e.key === 'B') this.setTool('box');
            else if (e.key === 's' || e.key === 'S') this.setTool('sphere');
            else if (e.key === 'p' || e.key === 'P') this.setTool('brush');
        });
    }

    setMode(mode) {
        this.mode = mode;
        $('modeTranslate').classList.toggle('on', mode === 'translate');
        $('modeRotate').classList.toggle('on', mode === 'rotate');
        $('modeScale').classList.toggle('on', mode === 'scale');
        this.attachGizmo();
    }

    setView(view) {
        this.view = view;
        for (const [id, v] of [['viewRest', 'rest'], ['viewStage1', 'stage1'], ['viewRefined', 'refined']]) $(id).classList.toggle('on', v === view);
        this.render();
    }

    bindButtons() {
        $('toolBox').onclick = () => this.setTool('box');
        $('toolSphere').onclick = () => this.setTool('sphere');
        $('toolBrush').onclick = () => this.setTool('brush');
        $('addFixed').onclick = () => this.addHandle(true);
        $('addMoving').onclick = () => this.addHandle(false);
        $('modeTranslate').onclick = () => this.setMode('translate');
        $('modeRotate').onclick = () => this.setMode('rotate');
        $('modeScale').onclick = () => this.setMode('scale');
        $('undo').onclick = () => this.undo();
        $('redo').onclick = () => this.redo();
        $('viewRest').onclick = () => this.setView('rest');
        $('viewStage1').onclick = () => this.setView('stage1');
        $('viewRefined').onclick = () => this.setView('refined');
        $('refine').onclick = () => this.refine();
        $('cancel').onclick = () => api('/api/cancel', { method: 'POST' }).catch((e) => this.setStatus(e.message));
        $('save').onclick = () => this.save($('saveName').value);
        $('addKey').onclick = () => this.addKey();
        $('play').onclick = () => this.play();
        $('saveAnim').onclick = () => this.saveAnimation($('saveName').value);
        $('frames').onchange = () => { $('scrub').max = this.frameCount() - 1; };
        $('scrub').oninput = () => this.scrub(+$('scrub').value);
    }

    updateButtons() {
        const running = this.progress.state === 'running';
        $('undo').disabled = this.history.length < 1;
        $('redo').disabled = !this.future.length;
        $('refine').disabled = running || !this.stage1;
        $('cancel').disabled = !running;
        $('save').disabled = running || !this.stage1;
        $('addKey').disabled = running || !this.handles.some((h) => !h.fixed);
        $('play').disabled = $('scrub').disabled = $('saveAnim').disabled = running || !this.keys.size;
    }

    // ---- keyframes: keys hold every moving handle's motion at a frame; animate runs the saved spec ----

    addKey() {
        const frame = Math.max(0, Math.min(+$('keyFrame').value | 0, this.frameCount() - 1));
        this.keys.set(frame, this.handles.map((h) => (h.fixed ? null : { translate: [...h.translate], quat: [...h.quat], scale: h.scale ?? 1 })));
        $('keys').textContent = `keys at ${[...this.keys.keys()].sort((a, b) => a - b).join(', ')}`;
        this.updateButtons();
    }

    frameCount() { return Math.max(1, +$('frames').value | 0); }

    /** The keyed spec `splatwarp animate` reads (samples/specs/README.md): each moving handle's keys. */
    animationSpec() {
        const frames = [...this.keys.keys()].sort((a, b) => a - b);
        const plain = this.spec();
        plain.handles = this.handles.map((h, i) => {
            if (h.fixed) return { nodes: h.nodes, fixed: true };
            const keys = frames.map((f) => {
                const m = this.keys.get(f)[i];
                return { frame: f, ...(m ? motionJson(m.translate, m.quat, m.scale) : motionJson([0, 0, 0], [0, 0, 0, 1], 1)) };
            });
            return { nodes: h.nodes, pivot: h.pivot, keys };
        });
        return { ...plain, frames: this.frameCount() };
    }

    /** Pose frame f of the keyed spec (the server interpolates as animate does). */
    scrub(f) {
        $('scrub').value = f;
        this.requestPose({ path: `/api/pose?frame=${f}`, spec: () => this.animationSpec() });
    }

    async play() {
        for (let f = 0; f < this.frameCount(); ++f) {
            const poses = this.poses;
            this.scrub(f);
            while (this.poses === poses && (this.posing || this.posePending)) await new Promise((r) => setTimeout(r, 15));
        }
    }

    async saveAnimation(name) {
        try {
            const res = await api(`/api/save-animation?name=${encodeURIComponent(name)}`, {
                method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(this.animationSpec()) });
            this.lastAnimation = await res.json();
            this.setStatus(`saved ${this.lastAnimation.file}\nreplay: ${this.lastAnimation.replay}`);
        } catch (e) {
            this.lastAnimation = { error: e.message };
            this.setStatus(e.message);
        }
    }

    // ---- refine, save ----

    async refine() {
        try {
            await api('/api/refine', { method: 'POST' });
            this.progress = { state: 'running' };
            this.updateButtons();
            while (this.progress.state === 'running') {
                await new Promise((r) => setTimeout(r, 200));
                this.progress = await (await api('/api/progress')).json();
                const p = this.progress;
                $('progress').value = p.total ? p.done / p.total : 0;
                this.setStatus(`refine: ${p.state} ${p.phase || ''} ${p.done}/${p.total}, ${(p.elapsedMs / 1000).toFixed(1)} s` + (p.error ? `: ${p.error}` : ''));
            }
            // Save and refine are open again as soon as the run ended, not once its model arrived:
            // a click in between did nothing (the browser test's save timed out under load).
            this.updateButtons();
            if (this.progress.state === 'done') {
                this.refined = decodeModel(await (await api('/api/refined')).arrayBuffer());
                $('viewRefined').disabled = false;
                $('progress').value = 1;
                this.setView('refined');
            }
        } catch (e) {
            this.setStatus(e.message);
        }
        this.updateButtons();
    }

    async save(name) {
        try {
            const res = await api('/api/save', { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify({ name }) });
            this.lastSave = await res.json();
            this.setStatus(`saved ${this.lastSave.dir}\nreplay: ${this.lastSave.replay}`);
        } catch (e) {
            this.lastSave = { error: e.message };
            this.setStatus(e.message);
        }
    }

    // ---- drawing ----

    render() {
        const model = this.shownModel();
        const tint = new Uint8Array(model.n);
        if (model.n === this.rest.n) {
            this.handles.forEach((h) => { for (const i of h.gaussians) if (i < model.n) tint[i] = h.fixed ? 2 : 1; });
            if (this.selection) for (const i of this.selection.gaussians) tint[i] = 3;
        }
        this.splats.show(model, tint);
    }

    /** The graph nodes a selection or handle catches, as small crosses drawn over the splats. */
    drawNodes() {
        if (!this.graph) return;
        const positions = [], colors = [], r = 0.01 * this.extent;
        const cross = (p, color) => {
            for (let a = 0; a < 3; ++a) {
                const d = [0, 0, 0];
                d[a] = r;
                positions.push(new pc.Vec3(p[0] - d[0], p[1] - d[1], p[2] - d[2]), new pc.Vec3(p[0] + d[0], p[1] + d[1], p[2] + d[2]));
                colors.push(color, color);
            }
        };
        const colorOf = (rgb) => new pc.Color(rgb[0], rgb[1], rgb[2]);
        this.handles.forEach((h) => { for (const j of h.nodes) cross(this.nodePosition(j, this.graph.nodes[j]), colorOf(HANDLE_COLORS[h.fixed ? 1 : 0])); });
        if (this.selection) for (const j of this.selection.nodes) cross(this.nodePosition(j, this.graph.nodes[j]), colorOf([1, 1, 0.2]));
        if (positions.length) this.app.drawLines(positions, colors, false);
    }

    setStatus(text) { $('status').textContent = text; }
}

/** A handle's motion as spec keys: translate, scale and rotate (axis, degrees) unless the identity. */
function motionJson(translate, quat, scale = 1) {
    const out = { translate };
    if (scale !== 1) out.scale = scale;
    const [x, y, z, w] = quat, s = Math.hypot(x, y, z);
    if (s > 1e-9) out.rotate = { axis: [x / s, y / s, z / s], degrees: (2 * Math.atan2(s, w) * 180) / Math.PI };
    return out;
}

/** p moved by a handle's motion: pivot + R (scale (p - pivot)) + translate. */
function applyMotion(h, p) {
    const q = new pc.Quat(h.quat[0], h.quat[1], h.quat[2], h.quat[3]);
    const k = h.scale ?? 1;
    const v = q.transformVector(new pc.Vec3(k * (p[0] - h.pivot[0]), k * (p[1] - h.pivot[1]), k * (p[2] - h.pivot[2])));
    return [v.x + h.pivot[0] + h.translate[0], v.y + h.pivot[1] + h.translate[1], v.z + h.pivot[2] + h.translate[2]];
}

const editor = new Editor();
// The test hook (tests/edit/browser-e2e.mjs): read-only state and the calls the UI makes.
window.splatwarpEditor = {
    get ready() { return editor.ready; },
    get poses() { return editor.poses; },
    get progress() { return editor.progress; },
    get lastSave() { return editor.lastSave; },
    get lastAnimation() { return editor.lastAnimation; },
    get handles() { return editor.handles.length; },
    /** The selection: indices of Gaussians and graph nodes, and the last sphere {centre, radius}. */
    get selection() { return editor.selection && { ...editor.selection, sphere: editor.lastSphere ?? null }; },
    /** Where the selectable Gaussians and the graph nodes are shown ([x,y,z] each). */
    shownPoints() {
        const m = editor.selectable().means, g = [];
        for (let i = 0; 3 * i < m.length; ++i) g.push([m[3 * i], m[3 * i + 1], m[3 * i + 2]]);
        return { gaussians: g, nodes: editor.graph.nodes.map((p, j) => editor.nodePosition(j, p)) };
    },
    get busy() { return editor.posing || editor.posePending; },
    /** Pixels of the canvas that differ from the clear colour (the test's "something is drawn"). */
    litPixels() {
        const c = document.createElement('canvas');
        [c.width, c.height] = [editor.canvas.width, editor.canvas.height];
        const g = c.getContext('2d');
        g.drawImage(editor.canvas, 0, 0);
        const d = g.getImageData(0, 0, c.width, c.height).data;
        let lit = 0;
        for (let i = 0; i < d.length; i += 4) if (Math.abs(d[i] - 31) + Math.abs(d[i + 1] - 31) + Math.abs(d[i + 2] - 36) > 24) ++lit;
        return lit;
    },
    /** The camera as the cross-check renders it: position, axes (right, up, forward), vertical fov, canvas pixels. */
    camera() {
        const e = editor.cameraEntity, v = (x) => [x.x, x.y, x.z];
        return { position: v(e.getPosition()), right: v(e.right), up: v(e.up), forward: v(e.forward), fov: e.camera.fov,
            width: editor.canvas.width, height: editor.canvas.height };
    },
    /** The canvas as a PNG data URL. */
    canvasPng: () => editor.canvas.toDataURL('image/png'),
    worldToScreen: (p) => editor.worldToScreen(p),
    bbox: () => ({ min: editor.graph.bboxMin, max: editor.graph.bboxMax }),
    nudge: (translate, degrees) => editor.nudge(translate, degrees),
    spec: () => editor.spec()
};
editor.start().catch((e) => { $('model').textContent = `failed: ${e.message || e}`; console.error(e); });
