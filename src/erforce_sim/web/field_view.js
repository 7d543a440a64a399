// The field view page: draws the newest frame of erforce_sim.field_view on a canvas, every
// animation frame. Frames arrive over the websocket /ws: live ones binary (decodeFrame; the layout
// is erforce_sim.view.field_view's FRAME_LAYOUT), replayed ones of a bag as JSON answers to
// {"replay": t} requests. Field coordinates: metres, x right, y up (REP 103), origin at the centre.
// window.fieldView.drawn says what the last animation frame drew (for tests and tools).
"use strict";

(function () {
  const COLORS = {
    grass: "#2b6b34", lines: "#f4f4f4", ours: "#2f7de1", opponent: "#f2d22e", ball: "#ff8a00",
    seen: "#ffd9a8", state: "#37d0ff", slide: "#ff4d4d", roll: "#37d0ff", stop: "#ffffff",
    catchPoint: "#ffffff", target: "#b6ff3b", follow: "#ff3bd4", wall: "#555c63",
    passSafe: "#4dff88", passUnsafe: "#ff4d8a",
  };
  const BALL_RADIUS_M = 0.0215;
  const PLOT_WINDOW_S = 6.0;
  const WHEEL_COLORS = ["#ff6b6b", "#4dd4ff", "#c6ff4d", "#ffb84d", "#d18cff", "#ffffff"];
  const PATH_MARK_PERIOD_S = 0.25, PATH_MAX_MARKS = 40; // as field_view.py's marks
  const PATH_CORNERS = 6; // as field_view.py's: the turns of the path off the walls in a frame
  // The binary frame (field_view.py FRAME_LAYOUT, SCALARS, ROBOT_COLUMNS)
  const FRAME_MAGIC = 0x31564645; // "EFV1" read as a little-endian uint32
  const FRAME_HEADER_BYTES = 24;
  const SCALARS = ["t", "truth_x", "truth_y", "truth_vx", "truth_vy", "truth_t", "seen_x", "seen_y", "state_x",
    "state_y", "state_vx", "state_vy", "stop_x", "stop_y", "v_shoot", "path_x", "path_y", "switch_x", "switch_y",
    "wall_x", "wall_y", "end_x", "end_y", "switch_time", "wall_time", "path_speed", "switch_speed", "wall_speed",
    "stop_time", ...Array.from({ length: PATH_CORNERS }, (_, k) => [`corner${k}_x`, `corner${k}_y`]).flat(),
    "receiver", "target_x", "target_y", "receiver_catch_time", "speed_truth", "speed_filtered", "speed_model"];
  const SCALAR_INDEX = Object.fromEntries(SCALARS.map((name, i) => [name, i]));
  const ROBOT_COLUMNS = 13; // kind, id, x, y, yaw, speed, truth, catch_time, catch_x, catch_y, ball_detected, counts
  const textDecoder = new TextDecoder();

  const canvas = document.getElementById("field");
  const ctx = canvas.getContext("2d");
  const statusLine = document.getElementById("status");
  const view = { scale: null, cx: 0, cy: 0, fitted: false }; // px per m, field point at the canvas centre
  let latest = null; // the newest frame
  let follow = null; // robot id followed
  let speedHistory = []; // [t, truth, filtered, model]
  let currentHistory = []; // [t, [avg currents]] of the followed robot
  let lastPlotT = -Infinity;
  const replay = { available: null, active: false, playing: true, speed: 1, t: 0, pending: false, lastWall: null };

  const fieldView = {
    drawn: null, frames: 0, fps: 0, messages: 0, errors: [], drawMs: 0, // drawMs: mean time of one redraw
    worldToPixel: (x, y) => [canvas.clientWidth / 2 + (x - view.cx) * view.scale,
                             canvas.clientHeight / 2 - (y - view.cy) * view.scale],
    pixelToWorld: (px, py) => [view.cx + (px - canvas.clientWidth / 2) / view.scale,
                               view.cy - (py - canvas.clientHeight / 2) / view.scale],
    follow: (id) => { follow = id; currentHistory = []; },
  };
  window.fieldView = fieldView;

  // ------------------------------------------------------------------ connection
  let socket = null;
  function connect() {
    socket = new WebSocket(`ws://${location.host}/ws`);
    socket.binaryType = "arraybuffer";
    socket.onopen = () => { statusLine.textContent = "connected"; socket.send(JSON.stringify({ info: 1 })); };
    socket.onclose = () => { statusLine.textContent = "disconnected; retrying ..."; setTimeout(connect, 1000); };
    socket.onmessage = (event) => {
      if (event.data instanceof ArrayBuffer) { // a live frame
        let frame;
        try { frame = decodeFrame(event.data); } catch (e) { fieldView.errors.push(String(e)); return; }
        fieldView.messages += 1;
        if (!replay.active) { take(frame); }
        return;
      }
      let message;
      try { message = JSON.parse(event.data); } catch (e) { return; }
      fieldView.messages += 1;
      if (message.error) { fieldView.errors.push(message.error); statusLine.textContent = message.error; }
      if (message.info) { setupReplay(message.info.replay); }
      if (message.frame) {
        const isReplay = Boolean(message.frame.replay);
        if (isReplay) { replay.pending = false; }
        if (isReplay === replay.active) { take(message.frame); }
      }
    };
  }

  // A binary frame as the object a JSON frame is (field_view.py decode_frame_bytes does the same); NaN: none.
  function decodeFrame(buffer) {
    const head = new DataView(buffer, 0, FRAME_HEADER_BYTES);
    if (buffer.byteLength < FRAME_HEADER_BYTES || head.getUint32(0, true) !== FRAME_MAGIC) { throw new Error("not a field view frame"); }
    const metaBytes = head.getUint32(4, true), numScalars = head.getUint32(8, true);
    const numRobots = head.getUint32(12, true), columns = head.getUint32(16, true);
    const scalarsAt = FRAME_HEADER_BYTES + metaBytes, robotsAt = scalarsAt + 8 * numScalars;
    if (numScalars !== SCALARS.length || buffer.byteLength !== robotsAt + 4 * numRobots * columns) {
      throw new Error("a field view frame of the wrong size");
    }
    const meta = JSON.parse(textDecoder.decode(new Uint8Array(buffer, FRAME_HEADER_BYTES, metaBytes)));
    const v = new Float64Array(buffer, scalarsAt, numScalars);
    const has = (x) => !Number.isNaN(x);
    const pair = (i) => (has(v[i]) ? [v[i], v[i + 1]] : null);
    const S = SCALAR_INDEX;
    const ball = { phase: meta.phase, uncertain: meta.uncertain, v_shoot: v[S.v_shoot] };
    if (has(v[S.truth_x])) { ball.truth = [v[S.truth_x], v[S.truth_y], v[S.truth_vx], v[S.truth_vy]]; ball.truth_t = v[S.truth_t]; }
    if (has(v[S.seen_x])) { ball.seen = pair(S.seen_x); }
    if (has(v[S.state_x])) { ball.state = [v[S.state_x], v[S.state_y], v[S.state_vx], v[S.state_vy]]; }
    const speed = { t: v[S.t] };
    if (has(v[S.speed_truth])) { speed.truth = v[S.speed_truth]; }
    if (has(v[S.speed_filtered])) { speed.filtered = v[S.speed_filtered]; }
    if (has(v[S.speed_model])) { speed.model = v[S.speed_model]; }
    const cells = new Float32Array(buffer, robotsAt, numRobots * columns);
    const wheels = (columns - ROBOT_COLUMNS) / 3;
    const robots = [];
    for (let i = 0, at = 0; i < numRobots; i++, at += columns) {
      const kind = cells[at], avgCount = cells[at + 11], currentCount = cells[at + 12];
      const avg = [], limit = [], current = [];
      for (let k = 0; k < avgCount; k++) {
        avg.push(cells[at + ROBOT_COLUMNS + k]); limit.push(cells[at + ROBOT_COLUMNS + wheels + k] !== 0);
      }
      for (let k = 0; k < currentCount; k++) { current.push(cells[at + ROBOT_COLUMNS + 2 * wheels + k]); }
      robots.push({
        id: kind === 2 ? `o${cells[at + 1]}` : cells[at + 1], team: kind === 0 ? "ours" : "opponent",
        pose: [cells[at + 2], cells[at + 3], cells[at + 4]], speed: cells[at + 5], truth: cells[at + 6] !== 0,
        catch_time: has(cells[at + 7]) ? cells[at + 7] : null,
        catch_point: has(cells[at + 8]) ? [cells[at + 8], cells[at + 9]] : null,
        avg_current: avg, limit_active: limit, current, ball_detected: cells[at + 10] !== 0,
      });
    }
    return {
      t: v[S.t], field: meta.field, robot_radius: meta.robot_radius, current_limit: meta.current_limit,
      model: meta.model, ball,
      path: has(v[S.path_x]) ? {
        start: pair(S.path_x), switch: pair(S.switch_x), wall: pair(S.wall_x), stop: pair(S.end_x),
        corners: Array.from({ length: PATH_CORNERS }, (_, k) => pair(S[`corner${k}_x`])).filter((c) => c !== null),
        switch_time: v[S.switch_time], wall_time: v[S.wall_time], stop_time: v[S.stop_time], speed: v[S.path_speed],
        switch_speed: v[S.switch_speed], wall_speed: v[S.wall_speed],
      } : null,
      stop_point: pair(S.stop_x), robots,
      receiver: has(v[S.receiver]) ? { id: v[S.receiver], target: pair(S.target_x), catch_time: v[S.receiver_catch_time] } : null,
      pass: meta.pass, speed, events: meta.events, rejected: meta.rejected,
    };
  }

  // The marks on the predicted path every PATH_MARK_PERIOD_S, up to the first wall (path.wall, the stop
  // point when it meets none): on each stretch the ball slows evenly from the speed at its start to the
  // speed at its end (path.speed, path.switch_speed, path.wall_speed).
  function pathMarks(path) {
    const marks = [];
    const length = Math.hypot(path.wall[0] - path.start[0], path.wall[1] - path.start[1]);
    if (!(length > 0) || !(path.wall_time > 0)) { return marks; }
    const ux = (path.wall[0] - path.start[0]) / length, uy = (path.wall[1] - path.start[1]) / length;
    const slideDistance = Math.hypot(path.switch[0] - path.start[0], path.switch[1] - path.start[1]);
    const rollTime = path.wall_time - path.switch_time, rollLoss = path.switch_speed - path.wall_speed;
    const count = Math.min(PATH_MAX_MARKS, Math.floor(path.wall_time / PATH_MARK_PERIOD_S));
    for (let k = 1; k <= count; k++) {
      const t = k * PATH_MARK_PERIOD_S;
      let d;
      if (t <= path.switch_time) {
        d = path.speed * t + 0.5 * (path.switch_speed - path.speed) / path.switch_time * t * t;
      } else {
        const tr = Math.min(t - path.switch_time, rollTime);
        d = slideDistance + path.switch_speed * tr - (rollTime > 0 ? 0.5 * rollLoss / rollTime * tr * tr : 0);
      }
      marks.push([path.start[0] + ux * d, path.start[1] + uy * d]);
    }
    return marks;
  }

  function take(frame) {
    if (latest && frame.t < latest.t - 0.5) { speedHistory = []; currentHistory = []; lastPlotT = -Infinity; }
    latest = frame;
    if (frame.t > lastPlotT) {
      lastPlotT = frame.t;
      const s = frame.speed;
      speedHistory.push([frame.t, s.truth, s.filtered, s.model]);
      const robot = followed(frame);
      if (robot && robot.avg_current.length) { currentHistory.push([frame.t, robot.avg_current]); }
      const cut = frame.t - PLOT_WINDOW_S;
      while (speedHistory.length && speedHistory[0][0] < cut) { speedHistory.shift(); }
      while (currentHistory.length && currentHistory[0][0] < cut) { currentHistory.shift(); }
    }
  }

  function followed(frame) {
    if (!frame || !frame.robots.length) { return null; }
    const id = follow !== null ? follow : frame.robots[0].id;
    return frame.robots.find((r) => r.id === id) || null;
  }

  // ---------------------------------------------------------------------- replay
  const replayBox = document.getElementById("replay");
  const slider = document.getElementById("slider");
  const playButton = document.getElementById("play");
  function setupReplay(info) {
    replay.available = info;
    if (!info) { return; }
    replayBox.hidden = false;
    slider.min = info.start; slider.max = info.end; slider.step = 0.01;
    replay.t = info.start;
    startReplay();
  }
  function startReplay() {
    replay.active = true; replay.lastWall = null; speedHistory = []; currentHistory = []; lastPlotT = -Infinity;
    document.getElementById("golive").textContent = "live";
  }
  playButton.onclick = () => {
    if (!replay.active) { startReplay(); }
    replay.playing = !replay.playing; playButton.textContent = replay.playing ? "pause" : "play";
  };
  document.getElementById("speed").onchange = (e) => { replay.speed = Number(e.target.value); };
  slider.oninput = () => { if (!replay.active) { startReplay(); } replay.t = Number(slider.value); };
  document.getElementById("golive").onclick = (e) => {
    if (replay.active) { replay.active = false; latest = null; e.target.textContent = "replay"; }
    else { startReplay(); }
  };
  function stepReplay(now) {
    if (!replay.active || !replay.available) { replay.lastWall = null; return; }
    if (replay.playing && replay.lastWall !== null) {
      replay.t = Math.min(replay.available.end, replay.t + (now - replay.lastWall) / 1000 * replay.speed);
    }
    replay.lastWall = now;
    slider.value = replay.t;
    document.getElementById("replaytime").textContent =
      `${replay.t.toFixed(2)} s of ${replay.available.start.toFixed(1)} – ${replay.available.end.toFixed(1)} s`;
    if (!replay.pending && socket && socket.readyState === WebSocket.OPEN) {
      replay.pending = true;
      socket.send(JSON.stringify({ replay: replay.t }));
    }
  }

  // ------------------------------------------------------------- pan, zoom, click
  let drag = null;
  canvas.addEventListener("mousedown", (e) => { drag = { x: e.clientX, y: e.clientY, moved: false }; });
  window.addEventListener("mouseup", (e) => {
    if (drag && !drag.moved) { pick(e); }
    drag = null;
  });
  window.addEventListener("mousemove", (e) => {
    if (!drag) { return; }
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    if (Math.abs(dx) + Math.abs(dy) > 2) { drag.moved = true; }
    view.cx -= dx / view.scale; view.cy += dy / view.scale;
    drag.x = e.clientX; drag.y = e.clientY;
  });
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    const rect = canvas.getBoundingClientRect();
    const px = e.clientX - rect.left, py = e.clientY - rect.top;
    const [wx, wy] = fieldView.pixelToWorld(px, py);
    view.scale = Math.min(2000, Math.max(5, view.scale * Math.exp(-e.deltaY * 0.0015)));
    const [nx, ny] = fieldView.pixelToWorld(px, py);
    view.cx += wx - nx; view.cy += wy - ny;
  }, { passive: false });
  canvas.addEventListener("dblclick", () => { view.fitted = false; });
  function pick(e) {
    if (!latest) { return; }
    const rect = canvas.getBoundingClientRect();
    const [wx, wy] = fieldView.pixelToWorld(e.clientX - rect.left, e.clientY - rect.top);
    let best = null, bestD = Infinity;
    for (const r of latest.robots) {
      const d = Math.hypot(r.pose[0] - wx, r.pose[1] - wy);
      if (d < bestD) { best = r; bestD = d; }
    }
    if (best && bestD <= Math.max(latest.robot_radius * 1.5, 12 / view.scale)) { fieldView.follow(best.id); }
  }

  // ---------------------------------------------------------------------- drawing
  function fit(frame) {
    const f = frame.field;
    const w = f.length + 2 * f.boundary + 0.4, h = f.width + 2 * f.boundary + 0.4;
    view.scale = Math.min(canvas.clientWidth / w, canvas.clientHeight / h);
    view.cx = 0; view.cy = 0; view.fitted = true;
  }

  function resize() {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.round(canvas.clientWidth * dpr), h = Math.round(canvas.clientHeight * dpr);
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  }

  function line(points, color, width, dash) {
    ctx.beginPath();
    points.forEach(([x, y], i) => { const [px, py] = fieldView.worldToPixel(x, y); i ? ctx.lineTo(px, py) : ctx.moveTo(px, py); });
    ctx.strokeStyle = color; ctx.lineWidth = width; ctx.setLineDash(dash || []); ctx.stroke(); ctx.setLineDash([]);
  }

  function disc(x, y, radiusPx, fill, stroke) {
    const [px, py] = fieldView.worldToPixel(x, y);
    ctx.beginPath(); ctx.arc(px, py, radiusPx, 0, 2 * Math.PI);
    if (fill) { ctx.fillStyle = fill; ctx.fill(); }
    if (stroke) { ctx.strokeStyle = stroke; ctx.lineWidth = 2; ctx.stroke(); }
    return [px, py];
  }

  function drawField(f) {
    const L = f.length / 2, W = f.width / 2, B = f.boundary;
    const [x0, y0] = fieldView.worldToPixel(-L - B, W + B);
    ctx.fillStyle = COLORS.grass; ctx.fillRect(x0, y0, (f.length + 2 * B) * view.scale, (f.width + 2 * B) * view.scale);
    line([[-L - B, -W - B], [L + B, -W - B], [L + B, W + B], [-L - B, W + B], [-L - B, -W - B]], COLORS.wall, 3);
    line([[-L, -W], [L, -W], [L, W], [-L, W], [-L, -W]], COLORS.lines, 1.5);
    line([[0, -W], [0, W]], COLORS.lines, 1.5);
    const [cx, cy] = fieldView.worldToPixel(0, 0);
    ctx.beginPath(); ctx.arc(cx, cy, f.centre_circle * view.scale, 0, 2 * Math.PI);
    ctx.strokeStyle = COLORS.lines; ctx.lineWidth = 1.5; ctx.stroke();
  }

  function drawRobot(r, radius, isFollowed) {
    const [x, y, yaw] = r.pose;
    const color = r.team === "opponent" ? COLORS.opponent : COLORS.ours;
    const rp = Math.max(4, radius * view.scale);
    const [px, py] = fieldView.worldToPixel(x, y);
    // the body: a circle flattened at the front (the dribbler), heading = yaw
    ctx.save(); ctx.translate(px, py); ctx.rotate(-yaw);
    const flat = Math.acos(0.75);
    ctx.beginPath(); ctx.arc(0, 0, rp, flat, 2 * Math.PI - flat); ctx.closePath();
    ctx.fillStyle = color; ctx.fill();
    ctx.strokeStyle = isFollowed ? COLORS.follow : "#0b0d10"; ctx.lineWidth = isFollowed ? 3 : 1; ctx.stroke();
    ctx.beginPath(); ctx.moveTo(0, 0); ctx.lineTo(rp * 0.75, 0); ctx.strokeStyle = "#0b0d10"; ctx.lineWidth = 2; ctx.stroke();
    ctx.restore();
    ctx.fillStyle = r.team === "opponent" ? "#000" : "#fff";
    ctx.font = `bold ${Math.max(10, Math.min(16, rp))}px sans-serif`;
    ctx.textAlign = "center"; ctx.textBaseline = "middle";
    ctx.fillText(String(r.id), px, py);
    return [px, py];
  }

  // The passing game's choice: an arrow from the passer to the receiver, green when the margin is safe,
  // the margin written at its middle; the opponent that would be first to the ball ringed.
  function drawPass(choice, robots) {
    const passer = robots.find((r) => r.id === choice.passer);
    const receiver = robots.find((r) => r.id === choice.receiver);
    if (!passer || !receiver) { return null; }
    const color = choice.safe ? COLORS.passSafe : COLORS.passUnsafe;
    const from = passer.pose.slice(0, 2), to = receiver.pose.slice(0, 2);
    line([from, to], color, 3, choice.safe ? [] : [8, 5]);
    const [fx, fy] = fieldView.worldToPixel(from[0], from[1]);
    const [tx, ty] = fieldView.worldToPixel(to[0], to[1]);
    const angle = Math.atan2(ty - fy, tx - fx), back = Math.max(8, 1.3 * robotPxRadius());
    const hx = tx - back * Math.cos(angle), hy = ty - back * Math.sin(angle);
    ctx.beginPath(); ctx.moveTo(hx, hy);
    ctx.lineTo(hx - 14 * Math.cos(angle - 0.4), hy - 14 * Math.sin(angle - 0.4));
    ctx.lineTo(hx - 14 * Math.cos(angle + 0.4), hy - 14 * Math.sin(angle + 0.4));
    ctx.closePath(); ctx.fillStyle = color; ctx.fill();
    const margin = choice.margin === null ? "no opponent can reach it" : `margin ${choice.margin >= 0 ? "+" : ""}${choice.margin.toFixed(2)} s`;
    const text = `pass ${choice.passer} → ${choice.receiver}: ${margin} (safe ≥ ${choice.safe_margin.toFixed(2)} s)`;
    ctx.font = "bold 12px sans-serif"; ctx.textAlign = "center"; ctx.textBaseline = "bottom";
    ctx.lineWidth = 3; ctx.strokeStyle = "#0b0d10"; ctx.strokeText(text, (fx + tx) / 2, (fy + ty) / 2 - 6);
    ctx.fillStyle = color; ctx.fillText(text, (fx + tx) / 2, (fy + ty) / 2 - 6);
    let opponentPx = null;
    const opponent = choice.first_opponent === null ? null : robots.find((r) => r.id === choice.first_opponent);
    if (opponent) {
      opponentPx = disc(opponent.pose[0], opponent.pose[1], robotPxRadius() + 6, null, COLORS.passUnsafe);
    }
    return { passer: choice.passer, receiver: choice.receiver, safe: choice.safe, margin: choice.margin,
             text, from_px: [fx, fy], to_px: [tx, ty], first_opponent: choice.first_opponent, opponent_px: opponentPx };
  }
  const robotPxRadius = () => Math.max(4, (latest ? latest.robot_radius : 0.09) * view.scale);

  function drawFrame(frame) {
    resize();
    if (!view.fitted) { fit(frame); }
    ctx.fillStyle = "#16191d"; ctx.fillRect(0, 0, canvas.clientWidth, canvas.clientHeight);
    drawField(frame.field);
    const drawn = { t: frame.t, robots: 0, robot_ids: [], robot_px: {}, catch_points: [], path: null,
                    ball_px: null, ball_world: null, ball_t: null, receiver: null, pass: null, scale: view.scale,
                    replay: Boolean(frame.replay) };
    const path = frame.path;
    if (path) {
      line([path.start, path.switch], COLORS.slide, 3);
      line([path.switch, path.wall, ...path.corners, path.stop], COLORS.roll, 3);  // off the walls to the stop
      const marks = pathMarks(path);
      for (const m of marks) { disc(m[0], m[1], 2, COLORS.lines); }
      drawn.path = { start: path.start, switch: path.switch, wall: path.wall, stop: path.stop,
                     wall_time: path.wall_time, stop_time: path.stop_time, marks };
    }
    if (frame.stop_point) {
      const [sx, sy] = fieldView.worldToPixel(frame.stop_point[0], frame.stop_point[1]);
      ctx.beginPath(); ctx.moveTo(sx - 6, sy - 6); ctx.lineTo(sx + 6, sy + 6); ctx.moveTo(sx + 6, sy - 6); ctx.lineTo(sx - 6, sy + 6);
      ctx.strokeStyle = COLORS.stop; ctx.lineWidth = 2; ctx.stroke();
    }
    const follower = followed(frame);
    for (const r of frame.robots) {
      if (r.catch_point) {
        const [cx, cy] = r.catch_point;
        const [px, py] = disc(cx, cy, 7, null, COLORS.catchPoint);
        ctx.fillStyle = COLORS.catchPoint; ctx.font = "11px sans-serif"; ctx.textAlign = "left"; ctx.textBaseline = "bottom";
        ctx.fillText(`${r.id}: ${r.catch_time.toFixed(2)} s`, px + 8, py - 4);
        line([r.pose.slice(0, 2), r.catch_point], "rgba(255,255,255,0.35)", 1, [4, 4]);
        drawn.catch_points.push({ id: r.id, world: r.catch_point, px: [px, py], time: r.catch_time });
      }
    }
    if (frame.receiver) {
      const [tx, ty] = fieldView.worldToPixel(frame.receiver.target[0], frame.receiver.target[1]);
      ctx.strokeStyle = COLORS.target; ctx.lineWidth = 3;
      ctx.beginPath(); ctx.arc(tx, ty, 11, 0, 2 * Math.PI);
      ctx.moveTo(tx - 16, ty); ctx.lineTo(tx + 16, ty); ctx.moveTo(tx, ty - 16); ctx.lineTo(tx, ty + 16); ctx.stroke();
      drawn.receiver = { id: frame.receiver.id, target: frame.receiver.target, px: [tx, ty] };
    }
    if (frame.pass) { drawn.pass = drawPass(frame.pass, frame.robots); }
    for (const r of frame.robots) {
      drawn.robot_px[r.id] = drawRobot(r, frame.robot_radius, follower && r.id === follower.id);
      drawn.robots += 1; drawn.robot_ids.push(r.id);
    }
    const ball = frame.ball;
    if (ball.seen) { disc(ball.seen[0], ball.seen[1], 2, COLORS.seen); }
    if (ball.state) { disc(ball.state[0], ball.state[1], Math.max(6, BALL_RADIUS_M * view.scale + 3), null, COLORS.state); }
    const shown = ball.truth || ball.state;
    if (shown) {
      drawn.ball_px = disc(shown[0], shown[1], Math.max(4, BALL_RADIUS_M * view.scale), COLORS.ball);
      drawn.ball_world = [shown[0], shown[1]];
      drawn.ball_t = ball.truth ? ball.truth_t : null;
    }
    ctx.fillStyle = "#fff"; ctx.font = "12px sans-serif"; ctx.textAlign = "right"; ctx.textBaseline = "top";
    ctx.fillText(`t ${frame.t.toFixed(2)} s · ${fieldView.fps.toFixed(0)} fps`, canvas.clientWidth - 8, 6);
    fieldView.drawn = drawn;
  }

  // ------------------------------------------------------------------------ plots
  function plot(canvasId, series, yMax, limit) {
    const c = document.getElementById(canvasId);
    const dpr = window.devicePixelRatio || 1;
    if (c.width !== c.clientWidth * dpr) { c.width = c.clientWidth * dpr; c.height = c.clientHeight * dpr; }
    const g = c.getContext("2d"); g.setTransform(dpr, 0, 0, dpr, 0, 0);
    const w = c.clientWidth, h = c.clientHeight;
    g.fillStyle = "#111417"; g.fillRect(0, 0, w, h);
    if (!series.length || !latest) { return; }
    const t1 = latest.t, t0 = t1 - PLOT_WINDOW_S;
    const X = (t) => 28 + (t - t0) / PLOT_WINDOW_S * (w - 32), Y = (v) => h - 12 - v / yMax * (h - 20);
    g.strokeStyle = "#333a42"; g.fillStyle = "#9aa4ae"; g.font = "10px sans-serif"; g.lineWidth = 1;
    for (let k = 0; k <= 2; k++) {
      const v = yMax * k / 2; g.beginPath(); g.moveTo(28, Y(v)); g.lineTo(w - 4, Y(v)); g.stroke();
      g.fillText(v.toFixed(1), 2, Y(v) + 3);
    }
    if (limit !== undefined) {
      g.strokeStyle = "#ff5c5c"; g.setLineDash([5, 4]); g.beginPath(); g.moveTo(28, Y(limit)); g.lineTo(w - 4, Y(limit));
      g.stroke(); g.setLineDash([]);
    }
    for (const { points, color, dash } of series) {
      g.strokeStyle = color; g.lineWidth = 1.5; g.setLineDash(dash || []); g.beginPath();
      let started = false;
      for (const [t, v] of points) {
        if (v === undefined || v === null) { started = false; continue; }
        const px = X(t), py = Y(Math.min(v, yMax));
        if (started) { g.lineTo(px, py); } else { g.moveTo(px, py); started = true; }
      }
      g.stroke(); g.setLineDash([]);
    }
  }

  function drawPlots(frame) {
    plot("speedplot", [
      { points: speedHistory.map((s) => [s[0], s[1]]), color: "#ffffff" },
      { points: speedHistory.map((s) => [s[0], s[2]]), color: "#37d0ff" },
      { points: speedHistory.map((s) => [s[0], s[3]]), color: "#ff8a00", dash: [5, 3] },
    ], 7.0);
    const wheels = currentHistory.length ? currentHistory[currentHistory.length - 1][1].length : 0;
    const series = [];
    for (let k = 0; k < wheels; k++) {
      series.push({ points: currentHistory.map((s) => [s[0], s[1][k]]), color: WHEEL_COLORS[k % WHEEL_COLORS.length] });
    }
    plot("currentplot", series, Math.max(2.0, frame.current_limit * 1.5), frame.current_limit);
  }

  // ----------------------------------------------------------------------- tables
  function rows(tableId, entries) {
    const html = entries.map(([k, v, cls]) => `<tr><td>${k}</td><td${cls ? ` class="${cls}"` : ""}>${v}</td></tr>`).join("");
    const table = document.getElementById(tableId);
    if (table.innerHTML !== html) { table.innerHTML = html; }
  }
  const f2 = (v) => (v === null || v === undefined ? "—" : v.toFixed(2));

  function drawNumbers(frame) {
    const r = followed(frame);
    document.getElementById("followtitle").textContent = r ? `Robot ${r.id} (${r.team})` : "Robot";
    document.getElementById("currenttitle").textContent = r ? `Motor currents of robot ${r.id} [A]` : "Motor currents [A]";
    if (r) {
      const limited = r.limit_active.some(Boolean);
      rows("numbers", [
        ["pose", `${f2(r.pose[0])}, ${f2(r.pose[1])} m, ${(r.pose[2] * 180 / Math.PI).toFixed(0)}°${r.truth ? "" : " (seen)"}`],
        ["speed", `${f2(r.speed)} m/s`],
        ["catch time", r.catch_time === null ? "—" : r.catch_time < 0 ? "never" : `${f2(r.catch_time)} s`],
        ["catch point", r.catch_point ? `${f2(r.catch_point[0])}, ${f2(r.catch_point[1])} m` : "—"],
        ["receiver", frame.receiver && frame.receiver.id === r.id ? "yes (the team's choice)" : "no"],
        ["pass", !frame.pass ? "—" : frame.pass.passer === r.id ? `to ${frame.pass.receiver}, ${frame.pass.kick_speed.toFixed(2)} m/s`
          : frame.pass.receiver === r.id ? `from ${frame.pass.passer}, ball there in ${f2(frame.pass.receiver_catch)} s` : "—"],
        ["avg current", r.avg_current.length ? r.avg_current.map(f2).join(" ") + " A" : "—"],
        ["current", r.current.length ? r.current.map(f2).join(" ") + " A" : "—"],
        ["current limit", limited ? `active (${frame.current_limit} A)` : `off (${frame.current_limit} A)`, limited ? "limit" : ""],
        ["light barrier", r.ball_detected ? "ball" : "—"],
      ]);
    } else {
      rows("numbers", [["", "no robot"]]);
    }
    const b = frame.ball, m = frame.model;
    const state = b.state;
    rows("ballnumbers", [
      ["phase", b.phase + (b.uncertain ? " (uncertain)" : "")],
      ["speed", state ? `${f2(Math.hypot(state[2], state[3]))} m/s (filtered)` : "—"],
      ["v_shoot", `${f2(b.v_shoot)} m/s`],
      ["stop", frame.path ? `in ${f2(frame.path.stop_time)} s at ${f2(frame.path.stop[0])}, ${f2(frame.path.stop[1])} m` : "—"],
      ["model", `a_slide ${m.a_slide.toFixed(2)}, a_roll ${m.a_roll.toFixed(3)} m/s², c_switch ${m.c_switch.toFixed(2)}`],
    ]);
    const events = frame.events.slice(-4).join("\n");
    const box = document.getElementById("events");
    if (box.textContent !== events) { box.textContent = events; }
  }

  // ------------------------------------------------------------------------- loop
  let fpsCount = 0, fpsStart = performance.now();
  function animate(now) {
    stepReplay(now);
    if (latest) {
      const start = performance.now();
      drawFrame(latest);
      drawPlots(latest);
      drawNumbers(latest);
      fieldView.drawMs += (performance.now() - start - fieldView.drawMs) * 0.05;
      fieldView.frames += 1; fpsCount += 1;
    }
    if (now - fpsStart >= 1000) { fieldView.fps = fpsCount * 1000 / (now - fpsStart); fpsCount = 0; fpsStart = now; }
    requestAnimationFrame(animate);
  }
  window.addEventListener("resize", () => { view.fitted = false; });
  connect();
  requestAnimationFrame(animate);
})();
