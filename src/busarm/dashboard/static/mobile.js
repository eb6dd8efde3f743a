/* busarm dashboard page, the mobile robot: driving the base, its odometry, the Lidar's
 * scan live, the map (a click on it names a point for transport), the mobile jobs.
 * Uses app.js's `window.busarm` (its socket, requests and message hooks).
 *
 * Safety, on the page's side, as for the arm's jog: driving is hold-to-move. A key,
 * button or the gamepad's trigger held sends `base_drive` at once and again every
 * 100 ms; letting go sends `base_stop`, as do the window losing focus, the page being
 * hidden, the pad going away. The server stops the wheels when the driver's page falls
 * silent for 250 ms.
 */
'use strict';

(() => {
  const B = window.busarm;
  const { $, el } = B;
  const RESEND_MS = 100;
  const PAD_DEADZONE = 0.2;
  const MOBILE_JOBS = ['transport', 'line follow', 'localise'];
  const PROGRESS_MAX = 40;
  // Each held direction adds this much of (vx, vy, wz) at full speed.
  const MOVES = {
    forward: [1, 0, 0], back: [-1, 0, 0], left: [0, 1, 0], right: [0, -1, 0],
    turn_left: [0, 0, 1], turn_right: [0, 0, -1],
  };
  const KEYS = { i: 'forward', k: 'back', j: 'left', l: 'right', u: 'turn_left', o: 'turn_right' };

  let limits = null;          // the robot's base: max_speed_m_s, max_yaw_rate_rad_s
  const held = new Map();     // what is held: source (key:KeyI, pointer, pad) -> direction
  let padTwist = null;        // the gamepad's twist, when its trigger is held
  let padBlocked = false;     // the pad ignored until its trigger is let go (after a blur)
  let sentTwist = null;       // the twist last sent (null: stopped)
  let resend = null;

  // ------------------------------------------------------------------ robot, panels

  function setRobot(r) {
    limits = r.base;
    $('base-panel').hidden = !r.base;
    $('mobile').hidden = !r.mobile;
    if (r.mobile) buildMobile(r.mobile);
    if (r.base) showSpeed();
  }
  B.on('welcome', (msg) => setRobot(msg.robot));
  B.on('robot', (msg) => setRobot(msg.robot));

  function speed() { return Number($('base-speed').value); }

  function showSpeed() {
    if (!limits) return;
    const deg = limits.max_yaw_rate_deg_s;
    $('base-speed-text').textContent =
      `${(speed() * limits.max_speed_m_s).toFixed(2)} m/s, ${(speed() * deg).toFixed(0)} deg/s`;
    $('base-limits').textContent =
      `limits: ${limits.max_speed_m_s.toFixed(2)} m/s, ${deg.toFixed(0)} deg/s (${limits.name})`;
  }
  $('base-speed').addEventListener('input', () => { showSpeed(); update(); });

  // ------------------------------------------------------------------ driving

  /** (vx, vy, wz) as fractions of the limits, scaled down so that together they stay
   * within the wheels' (each limit alone is within them: their sum at most 1 is). */
  function twistOf(f) {
    const total = Math.abs(f[0]) + Math.abs(f[1]) + Math.abs(f[2]);
    const k = (total > 1 ? 1 / total : 1) * speed();
    return [f[0] * k * limits.max_speed_m_s, f[1] * k * limits.max_speed_m_s,
      f[2] * k * limits.max_yaw_rate_rad_s];
  }

  /** The twist the held keys, buttons and pad ask for (m/s, m/s, rad/s). */
  function wanted() {
    if (!limits) return null;
    if (padTwist) return twistOf(padTwist);
    const sum = [0, 0, 0];
    for (const dir of new Set(held.values())) MOVES[dir].forEach((v, i) => { sum[i] += v; });
    if (sum.every((v) => v === 0)) return null;
    return twistOf(sum);
  }

  const round = (v) => Math.round(v * 1000) / 1000;

  /** Send what is held now: a drive (again every RESEND_MS while held), or a stop. */
  function update() {
    const t = wanted();
    if (!t) {
      clearInterval(resend);
      resend = null;
      if (sentTwist) B.send({ type: 'base_stop' });
      sentTwist = null;
    } else {
      const same = sentTwist && t.every((v, i) => Math.abs(v - sentTwist[i]) < 1e-4);
      sentTwist = t;
      if (!same) driveNow();
      if (!resend) resend = setInterval(driveNow, RESEND_MS);
    }
    markHeld();
  }

  function driveNow() {
    if (!sentTwist) return;
    B.request({ type: 'base_drive', vx_m_s: round(sentTwist[0]), vy_m_s: round(sentTwist[1]),
                wz_rad_s: round(sentTwist[2]) });
  }

  /** Let go of what ``source`` holds; with none, of everything (the pad too, until its
   * trigger is let go and pressed again). */
  function release(source) {
    if (source === undefined) {
      held.clear();
      if (padTwist) padBlocked = true;
      padTwist = null;
    } else {
      held.delete(source);
    }
    update();
  }

  function markHeld() {
    const dirs = new Set(held.values());
    for (const b of document.querySelectorAll('.bjog')) b.classList.toggle('held', dirs.has(b.dataset.base));
  }

  // A refused drive (a job runs, the robot is stopped): stop asking until released.
  B.on('error', (msg) => { if (msg.request === 'base_drive') release(); });

  document.addEventListener('pointerdown', (ev) => {
    const b = ev.target.closest('.bjog');
    if (!b || ev.button !== 0) return;
    ev.preventDefault();
    held.set('pointer', b.dataset.base);
    update();
  });
  document.addEventListener('pointerup', () => { if (held.has('pointer')) release('pointer'); });
  document.addEventListener('pointercancel', () => release('pointer'));
  document.addEventListener('pointerleave', (ev) => {
    if (ev.target.closest && ev.target.closest('.bjog')) release('pointer');
  }, true);
  $('base-stop').addEventListener('click', () => { release(); B.send({ type: 'base_stop' }); });

  document.addEventListener('keydown', (ev) => {
    if (ev.key === 'Escape') { release(); return; }
    if (B.typing(ev) || ev.ctrlKey || ev.altKey || ev.metaKey || !limits) return;
    const dir = KEYS[ev.key.toLowerCase()];
    if (!dir) return;
    ev.preventDefault();
    if (ev.repeat) return;
    held.set(`key:${ev.code}`, dir);
    update();
  });
  document.addEventListener('keyup', (ev) => {
    if (held.has(`key:${ev.code}`)) { ev.preventDefault(); release(`key:${ev.code}`); }
  });
  window.addEventListener('blur', () => release());
  window.addEventListener('pagehide', () => release());
  document.addEventListener('visibilitychange', () => { if (document.hidden) release(); });

  // Gamepad: a trigger (LT or RT) is the deadman; the left stick drives (up: forward,
  // left: left), the right stick's x turns.
  function pollPad() {
    const pads = navigator.getGamepads ? Array.from(navigator.getGamepads()) : [];
    const pad = pads.find((p) => p && p.connected);
    let next = null;
    if (pad && limits) {
      const down = (i) => Boolean(pad.buttons[i] && pad.buttons[i].pressed);
      const ax = (i) => {
        const v = typeof pad.axes[i] === 'number' ? pad.axes[i] : 0;
        return Math.abs(v) > PAD_DEADZONE ? v : 0;
      };
      const trigger = down(6) || down(7);
      if (!trigger) padBlocked = false;
      if (trigger && !padBlocked && !document.hidden && document.hasFocus()) {
        const f = [-ax(1), -ax(0), -ax(2)];  // fractions of the limits
        if (f.some((v) => v !== 0)) next = f;
      }
    }
    const changed = (next === null) !== (padTwist === null) ||
      (next && next.some((v, i) => Math.abs(v - padTwist[i]) > 0.01));
    if (changed) { padTwist = next; update(); }
    requestAnimationFrame(pollPad);
  }
  window.addEventListener('gamepaddisconnected', () => { padTwist = null; update(); });
  requestAnimationFrame(pollPad);

  // ------------------------------------------------------------------ odometry, scan

  const fmt = (v, d) => (typeof v === 'number' ? v.toFixed(d) : '–');

  B.on('state', (s) => {
    if (typeof s.map === 'number') loadMap(s.map);
    if (typeof s.has_map === 'boolean') showMapNote(s.has_map);
    const b = s.base;
    if (!b) return;
    if (b.error) { $('odom-source').textContent = b.error; return; }
    for (const [id, v, d] of [['odom-x', b.x_m, 3], ['odom-y', b.y_m, 3], ['odom-yaw', b.yaw_deg, 1]]) {
      $(id).textContent = fmt(v, d);
      $(id).dataset.value = String(v);
    }
    $('odom-v').textContent = `${fmt(b.vx_m_s, 2)}, ${fmt(b.vy_m_s, 2)} m/s, ${fmt(b.wz_deg_s, 0)} deg/s`;
    $('odom-source').textContent = `from ${b.source}` + (b.driving ? ' · driving' : '');
    $('base-panel').dataset.driving = b.driving ? '1' : '';
    $('scan-caption').textContent = s.lidar_error ? `Lidar: ${s.lidar_error}`
      : 'Lidar: the returns around the base (live, 1 m rings)';
  });

  let scansDrawn = 0;
  B.on('scan', (scan) => {
    drawScan($('scan-view'), scan.points_mm || []);
    scansDrawn += 1;
    const c = $('scan-view');
    c.dataset.scans = String(scansDrawn);
    c.dataset.points = String((scan.points_mm || []).length);
  });

  /** The scan's returns (mm, the base's frame) around the base, forward up. */
  function drawScan(canvas, points) {
    const ratio = window.devicePixelRatio || 1;
    const w = canvas.clientWidth || canvas.width;
    const h = canvas.clientHeight || canvas.height;
    if (canvas.width !== Math.round(w * ratio)) { canvas.width = Math.round(w * ratio); canvas.height = Math.round(h * ratio); }
    const g = canvas.getContext('2d');
    g.setTransform(ratio, 0, 0, ratio, 0, 0);
    g.fillStyle = '#111418'; g.fillRect(0, 0, w, h);
    const far = Math.max(1500, ...points.map(([x, y]) => Math.min(Math.hypot(x, y), 6000)));
    const scale = (Math.min(w, h) / 2 - 8) / far;  // px per mm
    const P = (x, y) => [w / 2 - y * scale, h / 2 - x * scale];  // x forward = up
    g.strokeStyle = '#2a303b'; g.fillStyle = '#5c6577'; g.font = '10px sans-serif';
    for (let r = 1000; r <= far; r += 1000) {
      g.beginPath(); g.arc(w / 2, h / 2, r * scale, 0, Math.PI * 2); g.stroke();
      g.fillText(`${r / 1000} m`, w / 2 + 3, h / 2 - r * scale + 11);
    }
    g.fillStyle = '#ff8c1a';
    for (const [x, y] of points) { const p = P(x, y); g.fillRect(p[0] - 1.5, p[1] - 1.5, 3, 3); }
    // The chassis (about 0.3 x 0.2 m) and its heading.
    const a = P(150, 100); const b = P(-150, -100);
    g.strokeStyle = '#4fa3ff'; g.lineWidth = 2;
    g.strokeRect(a[0], a[1], b[0] - a[0], b[1] - a[1]);
    const tip = P(300, 0);
    g.beginPath(); g.moveTo(w / 2, h / 2); g.lineTo(tip[0], tip[1]); g.stroke();
    g.lineWidth = 1;
  }

  // ------------------------------------------------------------------ the map

  let mapShown = -1;     // the number of the map picture shown
  let mapLoading = false;
  let mapInfo = null;    // GET /api/map: where the picture's metres are
  let mapSize = null;    // the shown picture's size (px): kept while the next one loads

  /** The map picture numbered ``n`` (GET /map.png), unless shown or on its way. */
  function loadMap(n) {
    if (n === mapShown || mapLoading) return;
    const img = $('map-view');
    mapLoading = true;
    img.onload = () => {
      mapLoading = false; mapShown = n; img.dataset.map = String(n);
      mapSize = [img.naturalWidth, img.naturalHeight];
      loadMapInfo();
    };
    img.onerror = () => { mapLoading = false; };  // the next state tries again
    img.src = B.withToken('/map.png', { n: String(n) });
  }

  async function loadMapInfo() {
    try {
      const reply = await fetch(B.withToken('/api/map'));
      mapInfo = reply.ok ? await reply.json() : null;
    } catch (e) { mapInfo = null; }
    const clickable = mapInfo && mapInfo.frame === 'map';
    $('map-view').classList.toggle('clickable', Boolean(clickable));
    $('map-caption').textContent = clickable
      ? 'map: click a spot to name a point there (for transport); path (blue), plan (grey), Lidar (orange), base (ring)'
      : 'map: path driven (blue), plan (grey), Lidar (orange), base (ring)';
  }

  let pointAt = null;
  $('map-view').addEventListener('click', (ev) => {
    const img = ev.currentTarget;
    if (!mapInfo || mapInfo.frame !== 'map' || !img.clientWidth || !mapSize) return;
    // The picture is fitted into the element (object-fit: contain), centred.
    const [w, h] = mapSize;
    const k = Math.min(img.clientWidth / w, img.clientHeight / h);
    const u = (ev.offsetX - (img.clientWidth - k * w) / 2) / k;
    const v = (ev.offsetY - (img.clientHeight - k * h) / 2) / k;
    if (!(u >= 0 && v >= 0 && u <= w && v <= h)) return;
    pointAt = [mapInfo.origin_x_m + u / mapInfo.px_per_m,
      mapInfo.origin_y_m + (mapInfo.height_px - v) / mapInfo.px_per_m];
    $('point-at').textContent = `x ${pointAt[0].toFixed(2)} m, y ${pointAt[1].toFixed(2)} m`;
    $('point-form').hidden = false;
    $('point-name').focus();
  });
  $('point-form').addEventListener('submit', (ev) => {
    ev.preventDefault();
    if (!pointAt) return;
    B.request({ type: 'name_point', name: $('point-name').value.trim(),
                x_m: round(pointAt[0]), y_m: round(pointAt[1]),
                yaw_deg: Number($('point-yaw').value) || 0 });
    $('point-form').hidden = true;
  });
  $('point-cancel').addEventListener('click', () => { $('point-form').hidden = true; });
  $('base-here').addEventListener('click', () => {
    if (!pointAt) return;
    B.request({ type: 'localise', x_m: round(pointAt[0]), y_m: round(pointAt[1]),
                yaw_deg: Number($('point-yaw').value) || 0 });
    $('point-form').hidden = true;
  });

  // ------------------------------------------------------------------ mobile jobs

  function buildMobile(m) {
    const fill = (sel, names, preferred) => {
      const keep = sel.value;
      sel.replaceChildren(...names.map((n) => el('option', { value: n }, n)));
      sel.value = names.includes(keep) ? keep : names.includes(preferred) ? preferred : names[0] || '';
    };
    fill($('tr-pick'), m.points || [], 'pick');
    fill($('tr-place'), m.points || [], 'place');
    const color = $('tr-color');
    if (color.options.length !== (m.colors || []).length + 1) {
      color.replaceChildren(el('option', { value: '' }, 'nearest'),
        ...(m.colors || []).map((c) => el('option', { value: c }, c)));
    }
    const box = $('lf-colors');
    if (box.childElementCount !== (m.colors || []).length) {
      box.replaceChildren(...(m.colors || []).map((c) => el('label', {},
        el('input', { type: 'checkbox', 'data-color': c, checked: c !== 'yellow' }), ` ${c}`)));
    }
    $('tr-run').disabled = !(m.points || []).length;
    pointsFile = m.points_file;
    showMapNote(m.map);
  }

  let pointsFile = null;
  function showMapNote(hasMap) {
    $('localise').disabled = !hasMap;
    const note = hasMap ? (pointsFile ? `points kept in ${pointsFile}` : '')
      : 'no map yet: a first transport on an arena twin maps it';
    if ($('map-note').textContent !== note) $('map-note').textContent = note;
  }

  /** A mobile job's progress line: a line on the same step (the words before its first
   * colon) replaces the one before it; the end is marked done, failed or stopped. */
  B.on('job', (msg) => {
    if (!MOBILE_JOBS.includes(msg.name)) return;
    const list = $('mobile-progress');
    const text = msg.state === 'running' ? msg.text : `${msg.state}: ${msg.text}`;
    const step = (t) => t.split(':')[0];
    const last = list.lastElementChild;
    if (msg.state === 'running' && last && !last.dataset.end && step(last.textContent) === step(text)) {
      last.textContent = text;
    } else {
      list.append(el('li', { class: msg.state === 'running' ? '' : msg.state,
                             'data-end': msg.state === 'running' ? null : msg.state }, text));
    }
    while (list.childElementCount > PROGRESS_MAX) list.firstElementChild.remove();
    list.scrollTop = list.scrollHeight;
  });

  const on = (id, fn) => $(id).addEventListener('click', fn);
  on('tr-run', () => {
    const color = $('tr-color').value;
    B.request({ type: 'transport', pick: $('tr-pick').value, place: $('tr-place').value,
                ...(color ? { color } : {}) });
  });
  on('lf-run', () => {
    const colors = Array.from(document.querySelectorAll('#lf-colors input:checked'))
      .map((c) => c.dataset.color);
    B.request({ type: 'line_follow', laps: Number($('lf-laps').value),
                speed_m_s: Number($('lf-speed').value), colors });
  });
  on('mobile-stop', () => B.request({ type: 'stop' }));
  on('localise', () => B.request({ type: 'localise' }));
})();
