/* busarm dashboard page: one WebSocket to /ws (busarm/dashboard/protocol.py documents the
 * messages), live values drawn from `state`, requests sent from the controls.
 *
 * Safety, on the page's side:
 * - E-STOP (the button or Escape) is sent from any page, driving or watching.
 * - Jogging is hold-to-move: a jog starts when a button, key or the gamepad's deadman is
 *   pressed and `jog_stop` is sent when it is released, when the pointer leaves the
 *   button, when the window loses focus or the page is hidden, when the pad goes away.
 * - A heartbeat goes out every 100 ms while connected: the server stops a jog when the
 *   driver's page falls silent for 300 ms (a frozen or closed page stops the arm).
 */
'use strict';

(() => {
  const HEARTBEAT_MS = 100;
  const RECONNECT_MIN_MS = 500;
  const RECONNECT_MAX_MS = 8000;
  const PAD_DEADZONE = 0.25;
  const LOG_MAX = 400;
  const BLANK = 'data:image/gif;base64,R0lGODlhAQABAIAAAAAAAP///yH5BAEAAAAALAAAAAABAAEAAAIBRAA7';
  // Keys: each pair moves the joint of that row + / - (first joint first).
  const JOINT_KEYS = [['q', 'a'], ['w', 's'], ['e', 'd'], ['r', 'f'], ['t', 'g'], ['y', 'h']];
  const AXIS_KEYS = {
    ArrowUp: ['x', 1], ArrowDown: ['x', -1], ArrowLeft: ['y', 1], ArrowRight: ['y', -1],
    PageUp: ['z', 1], PageDown: ['z', -1], Home: ['pitch', 1], End: ['pitch', -1],
  };
  const AXES = [['x', 'mm'], ['y', 'mm'], ['z', 'mm'], ['pitch', 'deg']];

  const params = new URLSearchParams(location.search);
  const token = params.get('token');
  const $ = (id) => document.getElementById(id);

  /** A same-origin URL with the page's token passed on (and extra query fields). */
  function withToken(path, extra) {
    const q = new URLSearchParams(extra || {});
    if (token) q.set('token', token);
    const s = q.toString();
    return s ? `${path}?${s}` : path;
  }

  /** A small element builder: el('td', {class: 'val'}, 'text', child, ...). */
  function el(tag, attrs, ...children) {
    const node = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (v === null || v === undefined || v === false) continue;
      if (k === 'class') node.className = v;
      else if (k === 'text') node.textContent = v;
      else if (k.startsWith('on')) node.addEventListener(k.slice(2), v);
      else node.setAttribute(k, v === true ? '' : v);
    }
    for (const c of children) node.append(c);
    return node;
  }

  // ------------------------------------------------------------------ state of the page

  let ws = null;
  let connected = false;
  let heartbeat = null;
  let reconnectDelay = RECONNECT_MIN_MS;
  let reconnectTimer = null;
  let me = null;        // this page's client id (p1, p2, ...)
  let driver = null;    // the driving page's id, or null
  let robot = null;     // the welcome's robot description
  let jog = null;       // the jog this page holds: {target, name, direction, speed, source}
  let stateCount = 0;
  let welcomeLog = new Set(); // the welcome's log lines: the same line may follow as `log`
  let lastState = null;
  const servoRows = new Map();

  function send(msg) {
    if (ws && ws.readyState === WebSocket.OPEN) {
      ws.send(JSON.stringify(msg));
      return true;
    }
    return false;
  }

  /** A request that moves or changes something: refused by the server if we watch. */
  function request(msg) {
    if (!send(msg)) toast(msg.type, 'not connected: nothing was sent');
  }

  // ------------------------------------------------------------------ connection

  function connect() {
    clearTimeout(reconnectTimer);
    const scheme = location.protocol === 'https:' ? 'wss:' : 'ws:';
    setConn('connecting…', false);
    const socket = new WebSocket(`${scheme}//${location.host}${withToken('/ws')}`);
    ws = socket;
    socket.onopen = () => {
      connected = true;
      reconnectDelay = RECONNECT_MIN_MS;
      setConn('connected', true);
      clearInterval(heartbeat);
      heartbeat = setInterval(() => send({ type: 'heartbeat' }), HEARTBEAT_MS);
    };
    socket.onmessage = (ev) => {
      let msg;
      try { msg = JSON.parse(ev.data); } catch (e) { return; }
      dispatch(msg);
    };
    socket.onclose = (ev) => {
      if (ws !== socket) return;
      const was = connected;
      connected = false;
      clearInterval(heartbeat);
      heartbeat = null;
      jog = null;   // the server stops a jog when the driver's page leaves
      markHeld();
      const delay = reconnectDelay;
      reconnectDelay = Math.min(RECONNECT_MAX_MS, reconnectDelay * 2);
      const why = ev.reason ? ` (${ev.reason})` : '';
      setConn(`connection lost${why}: retrying in ${(delay / 1000).toFixed(1)} s`, false);
      if (was) addLog({ t: Date.now() / 1000, level: 'error', text: `connection lost${why}` });
      reconnectTimer = setTimeout(connect, delay);
    };
  }

  function setConn(text, ok) {
    const c = $('conn');
    c.textContent = text;
    c.className = `pill ${ok ? 'ok' : 'lost'}`;
    c.dataset.state = ok ? 'connected' : 'lost';
    if (!ok) renderRole();
  }

  // ------------------------------------------------------------------ server messages

  const HANDLERS = {
    welcome(msg) {
      me = msg.client;
      driver = msg.role === 'driver' ? me : (lastState ? lastState.driver : null);
      setRobot(msg.robot);
      $('log').replaceChildren();
      welcomeLog = new Set((msg.log || []).map(logKey));
      for (const entry of msg.log || []) addLog(entry);
      renderRole();
      startCameras();
    },
    robot(msg) { setRobot(msg.robot); },
    state(msg) { renderState(msg); },
    log(msg) {
      if (welcomeLog.delete(logKey(msg))) return;  // shown already, from the welcome
      addLog(msg);
    },
    role(msg) { driver = msg.driver; renderRole(); },
    error(msg) {
      // A request refused unparsed comes back as "?": its text starts with its type.
      const named = /^([a-z_]+):/.exec(msg.text || '');
      if ((!msg.request || msg.request === '?') && named) msg.request = named[1];
      // A jog_stop refused because this page watches: its jog never ran; say nothing loud.
      if (msg.request === 'jog_stop' && driver !== me) return;
      if (msg.request === 'jog' && jog) jog.refused = true;
      toast(msg.request, msg.text);
    },
    job(msg) {
      const last = $('job-last');
      if (msg.state === 'running') {
        $('job').textContent = `${msg.name}: ${msg.text}`;
        $('job').className = 'job running';
      } else {
        last.textContent = `${msg.name} ${msg.state}: ${msg.text}`;
        last.className = `hint ${msg.state}`;
      }
    },
    report(msg) { showReport(msg.name); },
  };

  /** What other scripts of the page (mobile.js) hook into: each message kind's
   * listeners are called after this page's own handler, with the message. */
  const hooks = {};
  function dispatch(msg) {
    const handler = HANDLERS[msg.type];
    if (handler) handler(msg);
    for (const fn of hooks[msg.type] || []) fn(msg);
  }

  function setRobot(r) {
    robot = r;
    $('robot-name').textContent = r.name;
    $('robot-port').textContent = r.twin ? 'twin (real time)' : r.port;
    document.title = `busarm · ${r.name}`;
    buildJoints(r.joints);
    buildTool();
    buildKeysHelp(r.joints);
    buildPoses(r.poses);
    buildGroups(r.groups);
    buildColors(r.colors);
    const sorts = (r.bins || []).length > 0;
    $('pick-panel').hidden = !sorts;
    $('pick-none').hidden = sorts;
    $('fig-overview').hidden = !(r.cameras || []).includes('overview');
    $('fig-wrist').hidden = !(r.cameras || []).includes('wrist');
  }

  // ------------------------------------------------------------------ building controls

  function jogButton(target, name, direction, key) {
    const sign = direction > 0 ? '+1' : '-1';
    const label = direction > 0 ? '+' : '−';
    return el('button', {
      type: 'button', class: 'jog', 'data-jog': `${target}:${name}:${sign}`,
      title: `hold to jog ${name} ${label}${key ? ` (key ${key})` : ''}`,
    }, label);
  }

  function buildJoints(joints) {
    const body = $('joints').tBodies[0];
    body.replaceChildren();
    joints.forEach((j, i) => {
      const keys = JOINT_KEYS[i] || [];
      const zero = pct(0, j.min_deg, j.max_deg);
      const bar = el('div', { class: 'bar', title: `${j.min_deg}..${j.max_deg} deg` },
        el('div', { class: 'zero', style: `left:${zero}%`, hidden: zero === null }),
        el('div', { class: 'mark', 'data-bar': j.name }));
      body.append(el('tr', { 'data-joint-row': j.name },
        el('td', { class: 'name', title: `servo ${j.servo_id}` }, j.name),
        el('td', {}, jogButton('joint', j.name, -1, keys[1])),
        el('td', { class: 'val', 'data-joint': j.name, 'data-testid': `joint-${j.name}` }, '–'),
        el('td', { style: 'width:100%' }, bar),
        el('td', {}, jogButton('joint', j.name, 1, keys[0]))));
    });
  }

  function buildTool() {
    const body = $('tool').tBodies[0];
    if (body.rows.length) return;
    for (const [axis, unit] of AXES) {
      const keys = Object.entries(AXIS_KEYS).filter(([, v]) => v[0] === axis);
      const plus = keys.find(([, v]) => v[1] > 0);
      const minus = keys.find(([, v]) => v[1] < 0);
      body.append(el('tr', { 'data-axis-row': axis },
        el('td', { class: 'name' }, `${axis} `, el('span', { class: 'unit' }, unit)),
        el('td', {}, jogButton('axis', axis, -1, minus && minus[0])),
        el('td', { class: 'val', 'data-axis': axis, 'data-testid': `tool-${axis}` }, '–'),
        el('td', { style: 'width:100%' }),
        el('td', {}, jogButton('axis', axis, 1, plus && plus[0]))));
    }
  }

  function buildKeysHelp(joints) {
    const help = $('keys-help');
    help.replaceChildren();
    const line = (keys, text) => {
      const k = el('span');
      keys.forEach((key, i) => { if (i) k.append(' '); k.append(el('kbd', {}, key)); });
      help.append(k, el('span', {}, text));
    };
    joints.forEach((j, i) => {
      if (JOINT_KEYS[i]) line(JOINT_KEYS[i], `${j.name} + / −`);
    });
    line(['↑', '↓'], 'tool x + / − (forward)');
    line(['←', '→'], 'tool y + / − (left)');
    line(['PgUp', 'PgDn'], 'tool z + / −');
    line(['Home', 'End'], 'tool pitch + / −');
    line(['Esc'], 'E-STOP');
    line(['LB/RB'], 'pad deadman: left stick x/y, right stick z, d-pad pitch');
  }

  function buildPoses(poses) {
    const box = $('poses');
    box.replaceChildren(...(poses || []).map((name) => el('button', {
      type: 'button', class: 'drive-only', 'data-pose': name, title: `move to pose ${name}`,
      onclick: () => request({ type: 'move_pose', name }),
    }, name)));
  }

  function buildGroups(groups) {
    const sel = $('group-select');
    const keep = sel.value;
    sel.replaceChildren(...(groups || []).map((g) => el('option', { value: g }, g)));
    if ((groups || []).includes(keep)) sel.value = keep;
  }

  function buildColors(colors) {
    const box = $('pick-colors');
    if (box.childElementCount === (colors || []).length) return;
    box.replaceChildren(...(colors || []).map((c) => el('label', {},
      el('input', { type: 'checkbox', 'data-color': c, checked: c !== 'yellow' }), ` ${c}`)));
  }

  // ------------------------------------------------------------------ live values

  function pct(v, lo, hi) {
    if (!(hi > lo) || v < lo || v > hi) return null;
    return ((v - lo) / (hi - lo)) * 100;
  }

  const fmt = (v, digits = 1) => (typeof v === 'number' ? v.toFixed(digits) : '–');

  let drawnLinks = '';
  function renderState(s) {
    lastState = s;
    stateCount += 1;
    $('state-count').textContent = String(stateCount);
    if (typeof s.t === 'number') {
      const d = new Date(s.t * 1000);
      $('state-time').textContent = d.toLocaleTimeString([], { hour12: false }) +
        `.${String(d.getMilliseconds()).padStart(3, '0')}`;
    }
    if (s.driver !== driver) { driver = s.driver; renderRole(); }

    const halted = s.halted;
    $('halted-banner').hidden = halted === null || halted === undefined;
    if (halted) $('halted-reason').textContent = halted;
    $('robot-error').hidden = !s.error;
    if (s.error) $('robot-error').textContent = s.error;
    if (s.error || !robot) return;

    robot.joints.forEach((j, i) => {
      const v = s.joints_deg[i];
      const cell = document.querySelector(`[data-joint="${j.name}"]`);
      if (cell) { cell.textContent = fmt(v); cell.dataset.value = String(v); }
      const mark = document.querySelector(`[data-bar="${j.name}"]`);
      if (mark) {
        const p = pct(Math.min(Math.max(v, j.min_deg), j.max_deg), j.min_deg, j.max_deg);
        mark.style.left = `${p}%`;
        mark.classList.toggle('near', Math.min(v - j.min_deg, j.max_deg - v) < 5);
      }
    });
    const tool = s.tool || {};
    const toolValues = { x: tool.x_mm, y: tool.y_mm, z: tool.z_mm, pitch: tool.pitch_deg };
    for (const [axis] of AXES) {
      const cell = document.querySelector(`[data-axis="${axis}"]`);
      if (cell) { cell.textContent = fmt(toolValues[axis]); cell.dataset.value = String(toolValues[axis]); }
    }
    if (s.gripper) {
      $('gripper-gap').textContent = fmt(s.gripper.gap_mm);
      const gs = $('gripper-state');
      gs.textContent = s.gripper.state;
      gs.className = `badge ${s.gripper.state}`;
    }
    renderServos(s.servos || []);
    renderJob(s.job);
    $('rec-frames').textContent = s.recording === null || s.recording === undefined
      ? 'not recording' : `recording: ${s.recording} frame${s.recording === 1 ? '' : 's'}`;
    markMoving(s.jog);
    const links = JSON.stringify(s.links_mm || []);
    if (links !== drawnLinks) {  // redrawn only when the arm moved: the page stays light
      drawnLinks = links;
      window.busarmArmView.draw(s.links_mm || [], robot);
    }
  }

  function renderServos(servos) {
    const body = $('servos').tBodies[0];
    for (const sv of servos) {
      let row = servoRows.get(sv.id);
      if (!row) {
        const torque = el('button', {
          type: 'button', 'data-torque': String(sv.id), class: 'drive-only',
          onclick: () => {
            const on = row.torque.dataset.on === 'true';
            request({ type: 'torque', servo: sv.id, on: !on });
          },
        }, '–');
        const gid = robot && robot.gripper_id === sv.id ? ' (gripper)' : '';
        row = {
          tr: el('tr', { 'data-servo': String(sv.id) }),
          cells: [el('td', {}, `${sv.id}${gid}`), el('td'), el('td'), el('td', {}, torque), el('td')],
          torque,
        };
        row.tr.append(...row.cells);
        body.append(row.tr);
        servoRows.set(sv.id, row);
      }
      row.cells[1].textContent = fmt(sv.temp_c, 0);
      row.cells[2].textContent = fmt(sv.vin_v, 2);
      const t = sv.torque;
      row.torque.textContent = t === null ? '?' : t ? 'on' : 'off';
      row.torque.dataset.on = String(t === true);
      row.torque.className = `drive-only ${t ? 'torque-on' : 'torque-off'}`;
      row.torque.title = t ? 'torque on (holding): click to turn off (limp)'
        : 'torque off (limp): click to turn on (hold)';
      const alarms = (sv.alarms || []).join('; ');
      row.cells[4].textContent = alarms || '–';
      row.cells[4].className = alarms ? 'alarm' : 'muted';
    }
  }

  function renderJob(job) {
    const j = $('job');
    if (!job) { j.textContent = 'idle'; j.className = 'job'; return; }
    j.textContent = job.text ? `${job.name}: ${job.text}` : job.name;
    j.className = 'job running';
  }

  function renderRole() {
    const role = $('role');
    const driving = connected && me !== null && driver === me;
    if (!connected) role.textContent = 'not connected';
    else if (driving) role.textContent = 'you drive';
    else role.textContent = `watching (${driver ? `page ${driver} drives` : 'nobody drives'})`;
    role.className = driving ? 'driving' : 'watching';
    role.dataset.role = driving ? 'driver' : 'watcher';
    document.body.classList.toggle('watching', !driving);
    $('drive').hidden = !connected || driving || driver !== null;
    $('take-over').hidden = !connected || driving || driver === null;
    $('release').hidden = !connected || !driving;
  }

  function markMoving(j) {
    const want = j ? `${j.joint ? 'joint' : 'axis'}:${j.joint || j.axis}:${j.direction > 0 ? '+1' : '-1'}` : null;
    for (const b of document.querySelectorAll('.jog')) b.classList.toggle('moving', b.dataset.jog === want);
  }

  // ------------------------------------------------------------------ jogging (deadman)

  function speed() { return Number($('speed').value); }

  function startJog(target, name, direction, source, spd) {
    if (jog && jog.source === source && jog.target === target && jog.name === name &&
        jog.direction === direction) return;
    jog = { target, name, direction, source, speed: spd || speed(), refused: false };
    sendJog();
    markHeld();
  }

  function sendJog() {
    if (!jog) return;
    request({ type: 'jog', [jog.target]: jog.name, direction: jog.direction,
              speed: Math.round(jog.speed * 100) / 100 });
  }

  /** Stop the jog this page holds (only if ``source`` holds it, when given). */
  function stopJog(source) {
    if (!jog || (source && jog.source !== source)) return;
    jog = null;
    send({ type: 'jog_stop' });
    markHeld();
  }

  function markHeld() {
    const want = jog ? `${jog.target}:${jog.name}:${jog.direction > 0 ? '+1' : '-1'}` : null;
    for (const b of document.querySelectorAll('.jog')) b.classList.toggle('held', b.dataset.jog === want);
  }

  function jogFromButton(button) {
    const [target, name, sign] = button.dataset.jog.split(':');
    return [target, name, sign === '+1' ? 1 : -1];
  }

  document.addEventListener('pointerdown', (ev) => {
    const b = ev.target.closest('.jog');
    if (!b || ev.button !== 0) return;
    ev.preventDefault();
    const [target, name, dir] = jogFromButton(b);
    startJog(target, name, dir, `pointer:${b.dataset.jog}`);
  });
  const releasePointer = (ev) => {
    const b = ev.target.closest && ev.target.closest('.jog');
    if (b) stopJog(`pointer:${b.dataset.jog}`);
  };
  document.addEventListener('pointerup', (ev) => {
    if (jog && jog.source.startsWith('pointer:')) stopJog();  // released anywhere
    releasePointer(ev);
  });
  document.addEventListener('pointercancel', () => { if (jog && jog.source.startsWith('pointer:')) stopJog(); });
  document.addEventListener('pointerleave', releasePointer, true);  // left the button
  document.addEventListener('contextmenu', (ev) => { if (ev.target.closest('.jog')) ev.preventDefault(); });
  window.addEventListener('blur', () => stopJog());
  window.addEventListener('pagehide', () => stopJog());
  document.addEventListener('visibilitychange', () => { if (document.hidden) stopJog(); });

  $('speed').addEventListener('input', () => {
    $('speed-value').textContent = speed().toFixed(2);
    if (jog && jog.source !== 'pad' && !jog.refused) { jog.speed = speed(); sendJog(); }
  });

  // Keyboard: keydown starts (auto-repeat ignored), keyup stops; Escape is the e-stop.
  function keyJog(ev) {
    if (AXIS_KEYS[ev.key]) return ['axis', ...AXIS_KEYS[ev.key]];
    if (!robot || ev.key.length !== 1) return null;
    const k = ev.key.toLowerCase();
    for (let i = 0; i < robot.joints.length && i < JOINT_KEYS.length; i += 1) {
      const at = JOINT_KEYS[i].indexOf(k);
      if (at >= 0) return ['joint', robot.joints[i].name, at === 0 ? 1 : -1];
    }
    return null;
  }

  function typing(ev) {
    const t = ev.target;
    return t instanceof HTMLElement && (t.tagName === 'INPUT' && t.type !== 'range' &&
      t.type !== 'checkbox' || t.tagName === 'SELECT' || t.tagName === 'TEXTAREA' ||
      t.isContentEditable);
  }

  document.addEventListener('keydown', (ev) => {
    if (ev.key === 'Escape') { ev.preventDefault(); estop(); return; }
    if (typing(ev) || ev.ctrlKey || ev.altKey || ev.metaKey) return;
    const what = keyJog(ev);
    if (!what) return;
    ev.preventDefault();
    if (ev.repeat) return;
    startJog(what[0], what[1], what[2], `key:${ev.code}`);
  });
  document.addEventListener('keyup', (ev) => {
    if (jog && jog.source === `key:${ev.code}`) { ev.preventDefault(); stopJog(); }
  });

  // Gamepad: polled each animation frame. A shoulder button (LB or RB) is the deadman:
  // held, the left stick jogs the tool in x (up) and y (left), the right stick in z, the
  // d-pad its pitch; the strongest one wins (one jog at a time).
  function pollPad() {
    const pads = navigator.getGamepads ? Array.from(navigator.getGamepads()) : [];
    const pad = pads.find((p) => p && p.connected);
    const status = $('pad-status');
    if (!pad) {
      stopJog('pad');
      if (status.dataset.pad) { status.textContent = 'No gamepad.'; delete status.dataset.pad; }
    } else {
      const down = (i) => Boolean(pad.buttons[i] && pad.buttons[i].pressed);
      const deadman = down(4) || down(5);
      const text = `Gamepad: ${pad.id.slice(0, 40)}${deadman ? ' (deadman held)' : ' (hold LB or RB to move)'}`;
      if (status.textContent !== text) { status.textContent = text; status.dataset.pad = '1'; }
      const ax = (i) => (typeof pad.axes[i] === 'number' ? pad.axes[i] : 0);
      const inputs = [['x', -ax(1)], ['y', -ax(0)], ['z', -ax(3)],
        ['pitch', (down(12) ? 1 : 0) - (down(13) ? 1 : 0)]];
      let best = null;
      for (const [axis, v] of inputs) if (Math.abs(v) > PAD_DEADZONE && (!best || Math.abs(v) > Math.abs(best[1]))) best = [axis, v];
      if (!deadman || !best) {
        stopJog('pad');
      } else {
        const dir = best[1] > 0 ? 1 : -1;
        const spd = Math.min(1, Math.max(0.05, Math.round(Math.abs(best[1]) * speed() * 20) / 20));
        if (jog && jog.source === 'pad' && jog.name === best[0] && jog.direction === dir) {
          if (Math.abs(jog.speed - spd) >= 0.05 && !jog.refused) { jog.speed = spd; sendJog(); }
        } else {
          startJog('axis', best[0], dir, 'pad', spd);
        }
      }
    }
    requestAnimationFrame(pollPad);
  }
  window.addEventListener('gamepaddisconnected', () => stopJog('pad'));

  // ------------------------------------------------------------------ e-stop and buttons

  function estop() {
    stopJog();
    if (!send({ type: 'estop' })) toast('estop', 'NOT CONNECTED: the e-stop was not sent. Cut the power!');
  }
  $('estop').addEventListener('pointerdown', (ev) => { if (ev.button === 0) estop(); });
  $('estop').addEventListener('click', (ev) => { if (ev.detail === 0) estop(); }); // keyboard

  const on = (id, fn) => $(id).addEventListener('click', fn);
  on('rearm', () => request({ type: 'rearm' }));
  on('drive', () => request({ type: 'drive' }));
  on('take-over', () => request({ type: 'drive', take_over: true }));
  on('release', () => { stopJog(); request({ type: 'release' }); });
  on('grip-open', () => request({ type: 'gripper', action: 'open' }));
  on('grip-close', () => request({ type: 'gripper', action: 'close' }));
  on('job-stop', () => request({ type: 'stop' }));
  on('group-stop', () => request({ type: 'stop' }));
  on('play', () => {
    const group = $('group-select').value;
    if (group) request({ type: 'play', group });
  });
  on('save-pose', () => request({ type: 'save_pose', name: $('pose-name').value.trim() }));
  on('rec-start', () => request({ type: 'record', action: 'start' }));
  on('rec-frame', () => request({ type: 'record', action: 'frame',
                                  duration_ms: Math.round(Number($('rec-duration').value)) }));
  on('rec-save', () => request({ type: 'record', action: 'save', name: $('rec-name').value.trim() }));
  on('rec-cancel', () => request({ type: 'record', action: 'cancel' }));
  on('pick-run', () => {
    const colors = Array.from(document.querySelectorAll('#pick-colors input:checked'))
      .map((c) => c.dataset.color);
    request({ type: 'pick_sort', colors, order: $('pick-order').value, by: $('pick-by').value });
  });

  // ------------------------------------------------------------------ cameras, report

  function startCameras() {
    const show = $('cameras-toggle').checked;
    for (const name of ['wrist', 'overview']) {
      const img = $(`cam-${name}`);
      const wanted = show && robot && (robot.cameras || []).includes(name);
      const url = wanted ? withToken(`/camera/${name}.mjpg`, { n: String(Date.now()) }) : BLANK;
      img.dataset.live = wanted ? '1' : '';
      img.src = url;
    }
  }
  for (const img of [$('cam-wrist'), $('cam-overview')]) {
    img.addEventListener('error', () => {  // a stream cut (server restarted): retry
      if (img.dataset.live) setTimeout(() => { if (img.dataset.live && connected) startCameras(); }, 2000);
    });
  }
  $('cameras-toggle').addEventListener('change', startCameras);
  if (params.get('cameras') === 'off') $('cameras-toggle').checked = false;

  function showReport(name) {
    const base = `/reports/${encodeURIComponent(name)}/`;
    $('report').hidden = false;
    const link = $('report-link');
    link.href = withToken(`${base}report.json`);
    link.textContent = `${name}/report.json`;
    for (const [which, file] of [['before', 'before.png'], ['after', 'after.png'],
      ['camera', 'camera.gif']]) {
      const img = $(`report-${which}`);
      img.hidden = false;
      img.onerror = () => { img.hidden = true; };  // not in this report (a stopped run)
      img.src = withToken(`${base}${file}`, { n: String(Date.now()) });
    }
  }

  // ------------------------------------------------------------------ log, errors

  function logKey(entry) { return `${entry.t}|${entry.text}`; }

  function addLog(entry) {
    const log = $('log');
    const atEnd = log.scrollTop + log.clientHeight >= log.scrollHeight - 4;
    const d = new Date((entry.t || Date.now() / 1000) * 1000);
    log.append(el('li', { class: entry.level || 'info' },
      el('span', { class: 't' }, d.toLocaleTimeString([], { hour12: false })), entry.text));
    while (log.childElementCount > LOG_MAX) log.firstElementChild.remove();
    if (atEnd) log.scrollTop = log.scrollHeight;
  }

  function toast(what, text) {
    const box = el('div', { class: 'toast', role: 'alert', 'data-testid': 'error-toast', 'data-request': what || '' },
      el('b', {}, `Refused ${what || 'request'}: `), text);
    $('toasts').append(box);
    while ($('toasts').childElementCount > 4) $('toasts').firstElementChild.remove();
    setTimeout(() => box.remove(), 6000);
    addLog({ t: Date.now() / 1000, level: 'error', text: `refused ${what || 'request'}: ${text}` });
  }

  window.busarm = {
    $, el, send, request, toast, withToken,
    /** Call ``fn(msg)`` with every message of ``kind`` (after the page's own handling). */
    on(kind, fn) { (hooks[kind] = hooks[kind] || []).push(fn); },
    robot: () => robot,
    driving: () => connected && me !== null && driver === me,
    typing,
  };

  renderRole();
  // Once every script of the page has run (mobile.js hooks into the welcome).
  if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', connect);
  else connect();
  requestAnimationFrame(pollPad);
})();
