// The block page of 'parmor blocks': blocks generated from the design's behaviours
// (window.PARMOR_CONFIG, written by parmor into config.js), the Python program they stand
// for (a Blockly generator), and, when the page is served by 'parmor blocks DIR --serve',
// a Run button that posts the program as JSON and shows the reply: the path travelled,
// the verdict figures and the robot moving (three.js).
/* global Blockly */
'use strict';

(function () {
  const config = window.PARMOR_CONFIG;
  const served = location.protocol === 'http:' || location.protocol === 'https:';
  const PROGRAM = 'parmor_program';
  const DO = 'parmor_do:';
  const REPEAT = 'parmor_repeat';
  const WAIT = 'parmor_wait';
  const IF = 'parmor_if';
  const OPS = ['<', '<=', '>', '>=', '==', '!='];
  const COLOURS = { program: 45, behaviour: 210, control: 120, sensing: 290 };

  // --- numbers and strings as Python writes them ---------------------------------------

  /** The program's text of a number (program.script.number_text): integral values below
   * 1e21 as integers, others as Python's repr(float). */
  function pyNumber(x) {
    if (Number.isInteger(x) && Math.abs(x) < 1e21) return BigInt(x).toString();
    if (!Number.isFinite(x)) throw new Error('not a finite number: ' + x);
    // the shortest digits that read back as x (both languages use them), then Python's
    // layout: fixed for 1e-4 <= |x| < 1e16, else d.ddde-XX (two exponent digits at least)
    const [mant, e] = x.toExponential().split('e');
    const exp = Number(e);
    if (exp >= -4 && exp < 16) return String(x);
    const sign = exp < 0 ? '-' : '+';
    const digits = String(Math.abs(exp)).padStart(2, '0');
    return mant + 'e' + sign + digits;
  }

  function pyValue(v) {
    return typeof v === 'string' ? JSON.stringify(v) : pyNumber(v);
  }

  /** A limit or value short enough for a label. */
  function short(x) {
    return Number.isInteger(x) ? String(x) : String(Number(x.toPrecision(4)));
  }

  // --- units as a novice reads them (program.blocks.DISPLAY_UNITS) -----------------------
  // A parameter's field shows value x display.scale in display.unit (angles in degrees);
  // the program, its Python text and the server keep the API's units.

  function disp(p) {
    return p.display || { unit: p.unit, scale: 1, step: null };
  }

  /** The value shown for ``x`` in the API's unit (rounded to the field's step). */
  function shown(p, x) {
    const d = disp(p);
    const v = x * d.scale;
    return d.step ? Math.round(v / d.step) * d.step : v;
  }

  /** A limit as shown (not rounded: a shown value is judged against it). */
  function shownLimit(p, x) {
    return x === null ? null : x * disp(p).scale;
  }

  /** The API's value of a shown one; a value on a limit up to rounding is the limit. */
  function fromShown(p, v) {
    const d = disp(p);
    let x = d.scale === 1 ? v : v / d.scale;
    const tol = 1e-9 * Math.max(1, Math.abs(x));
    if (p.low !== null && x < p.low && p.low - x <= tol) x = p.low;
    if (p.high !== null && x > p.high && x - p.high <= tol) x = p.high;
    return x;
  }

  function rangeText(p) {
    if (p.kind === 'choice') return '';
    const lo = p.low === null ? '-inf' : short(shownLimit(p, p.low));
    const hi = p.high === null ? 'inf' : short(shownLimit(p, p.high));
    const unit = disp(p).unit;
    return (unit ? unit + ' ' : '') + '[' + lo + ', ' + hi + ']';
  }

  // --- the blocks ----------------------------------------------------------------------

  const behaviours = {};
  for (const spec of config.toolbox) behaviours[spec.name] = spec;

  Blockly.Blocks[PROGRAM] = {
    init() {
      this.appendDummyInput().appendField('program for ' + config.robot_type);
      this.appendStatementInput('BODY');
      this.setColour(COLOURS.program);
      this.setDeletable(false);
      this.setTooltip('The program: the blocks inside run from top to bottom when you press Run.');
    },
  };

  for (const spec of config.toolbox) {
    Blockly.Blocks[DO + spec.name] = {
      init() {
        this.appendDummyInput().appendField(spec.name);
        for (const p of spec.params) {
          const row = this.appendDummyInput('P_' + p.name).appendField('  ' + p.name);
          if (p.kind === 'choice') {
            row.appendField(new Blockly.FieldDropdown(p.choices.map((c) => [c, c])), p.name);
            this.setFieldValue(p.default, p.name);
          } else {
            const precision = p.kind === 'int' ? 1 : disp(p).step || undefined;
            row.appendField(
              new Blockly.FieldNumber(shown(p, p.default), undefined, undefined, precision),
              p.name,
            );
            row.appendField(rangeText(p));
          }
        }
        this.setPreviousStatement(true);
        this.setNextStatement(true);
        this.setColour(COLOURS.behaviour);
        const docs = spec.params.map(
          (p) => p.name + ': ' + p.doc + (p.kind === 'choice' ? '' : ' (' + rangeText(p) + ')'),
        );
        this.setTooltip([spec.doc].concat(docs).join('\n'));
      },
    };
  }

  Blockly.Blocks[REPEAT] = {
    init() {
      this.appendDummyInput()
        .appendField('repeat')
        .appendField(new Blockly.FieldNumber(2, 0, undefined, 1), 'TIMES')
        .appendField('times');
      this.appendStatementInput('BODY');
      this.setPreviousStatement(true);
      this.setNextStatement(true);
      this.setColour(COLOURS.control);
      this.setTooltip('Run the blocks inside this many times.');
    },
  };

  Blockly.Blocks[WAIT] = {
    init() {
      this.appendDummyInput()
        .appendField('wait')
        .appendField(new Blockly.FieldNumber(1, 0), 'SECONDS')
        .appendField('s');
      this.setPreviousStatement(true);
      this.setNextStatement(true);
      this.setColour(COLOURS.control);
      this.setTooltip('Stand still for this many seconds.');
    },
  };

  Blockly.Blocks[IF] = {
    init() {
      const reports = config.reports.map((r) => [r.name + (r.unit ? ' (' + r.unit + ')' : ''), r.name]);
      this.appendDummyInput()
        .appendField('if the robot reports')
        .appendField(new Blockly.FieldDropdown(reports), 'REPORT')
        .appendField(new Blockly.FieldDropdown(OPS.map((o) => [o, o])), 'OP')
        .appendField(new Blockly.FieldNumber(0), 'VALUE');
      this.appendStatementInput('THEN').appendField('then');
      this.appendStatementInput('ELSE').appendField('else');
      this.setPreviousStatement(true);
      this.setNextStatement(true);
      this.setColour(COLOURS.sensing);
      this.setTooltip(
        'Compare what the robot reports with a number.\n' +
          config.reports.map((r) => r.name + ': ' + r.doc).join('\n'),
      );
    },
  };

  // --- the program as JSON (what Run sends) --------------------------------------------

  function numberField(block, name) {
    return Number(block.getFieldValue(name));
  }

  /** A behaviour block's parameter in the API's unit (a choice as it is): the default
   * itself while the field shows it (a design's own value, e.g. its speed, then plans as
   * when not given; a field in degrees would send it rounded to 0.1 degree), else the
   * shown value's. */
  function paramValue(block, p) {
    if (p.kind === 'choice') return block.getFieldValue(p.name);
    const v = numberField(block, p.name);
    const d = disp(p);
    const tol = d.step ? d.step / 2 : 1e-12 * Math.max(1, Math.abs(v));
    if (typeof p.default === 'number' && Math.abs(v - shown(p, p.default)) < tol) return p.default;
    return fromShown(p, v);
  }

  function statementJson(block) {
    const type = block.type;
    if (type.startsWith(DO)) {
      const spec = behaviours[type.slice(DO.length)];
      const params = {};
      for (const p of spec.params) {
        params[p.name] = paramValue(block, p);
      }
      return { do: spec.name, params };
    }
    if (type === REPEAT) {
      return { repeat: numberField(block, 'TIMES'), body: listJson(block.getInputTargetBlock('BODY')) };
    }
    if (type === WAIT) return { wait: numberField(block, 'SECONDS') };
    if (type === IF) {
      return {
        if: {
          report: block.getFieldValue('REPORT'),
          op: block.getFieldValue('OP'),
          value: numberField(block, 'VALUE'),
        },
        then: listJson(block.getInputTargetBlock('THEN')),
        else: listJson(block.getInputTargetBlock('ELSE')),
      };
    }
    throw new Error('unknown block ' + type);
  }

  function listJson(first) {
    const out = [];
    for (let b = first; b; b = b.getNextBlock()) {
      if (b.isEnabled()) out.push(statementJson(b));
    }
    return out;
  }

  // --- the Python program (a Blockly generator) ----------------------------------------

  const python = new Blockly.Generator('ParmorPython');
  python.INDENT = '    ';

  function body(block, name, gen) {
    return gen.statementToCode(block, name) || gen.INDENT + 'pass\n';
  }

  python.forBlock[PROGRAM] = function (block, gen) {
    return config.python_header + 'def main(robot):\n' + body(block, 'BODY', gen);
  };
  for (const spec of config.toolbox) {
    python.forBlock[DO + spec.name] = function (block) {
      const args = spec.params.map((p) => {
        const v = paramValue(block, p);
        return ', ' + p.name + '=' + pyValue(v);
      });
      return 'robot.do(' + JSON.stringify(spec.name) + args.join('') + ')\n';
    };
  }
  python.forBlock[REPEAT] = function (block, gen) {
    return 'for _ in range(' + pyNumber(numberField(block, 'TIMES')) + '):\n' + body(block, 'BODY', gen);
  };
  python.forBlock[WAIT] = function (block) {
    return 'robot.wait(' + pyNumber(numberField(block, 'SECONDS')) + ')\n';
  };
  python.forBlock[IF] = function (block, gen) {
    const cond =
      'robot.report(' + JSON.stringify(block.getFieldValue('REPORT')) + ') ' +
      block.getFieldValue('OP') + ' ' + pyNumber(numberField(block, 'VALUE'));
    return 'if ' + cond + ':\n' + body(block, 'THEN', gen) + 'else:\n' + body(block, 'ELSE', gen);
  };
  // a statement's text is followed by the statements under it
  python.scrub_ = function (block, code, thisOnly) {
    const next = block.nextConnection && block.nextConnection.targetBlock();
    return next && !thisOnly ? code + this.blockToCode(next) : code;
  };

  // --- the workspace -------------------------------------------------------------------

  const toolbox = {
    kind: 'categoryToolbox',
    contents: [
      {
        kind: 'category',
        name: 'Behaviours',
        colour: String(COLOURS.behaviour),
        contents: config.toolbox.map((spec) => ({ kind: 'block', type: DO + spec.name })),
      },
      {
        kind: 'category',
        name: 'Control',
        colour: String(COLOURS.control),
        contents: [REPEAT, WAIT, IF].map((type) => ({ kind: 'block', type })),
      },
    ],
  };

  const workspace = Blockly.inject('blockly', {
    toolbox,
    media: 'vendor/media/',
    sounds: false,
    trashcan: true,
    move: { scrollbars: true, drag: true, wheel: true },
    zoom: { controls: true, startScale: 0.8 },
  });
  const start = workspace.newBlock(PROGRAM);
  start.initSvg();
  start.render();
  start.moveBy(30, 20);

  function programJson() {
    return { program: listJson(start.getInputTargetBlock('BODY')) };
  }

  function pythonText() {
    python.init(workspace);
    return python.blockToCode(start, true);
  }

  /** The fields of a behaviour block beyond their limits, as messages. */
  function outOfRange(block) {
    const spec = behaviours[block.type.slice(DO.length)];
    const bad = [];
    for (const p of spec.params) {
      if (p.kind === 'choice') continue;
      const x = paramValue(block, p);
      if ((p.low !== null && x < p.low) || (p.high !== null && x > p.high)) {
        bad.push(spec.name + ': ' + p.name + ' ' + short(numberField(block, p.name)) +
          ' is outside ' + rangeText(p));
      }
    }
    return bad;
  }

  /** Every out-of-range field of the program's enabled blocks (what Run refuses). */
  function programOutOfRange() {
    const bad = [];
    for (const block of start.getDescendants(false)) {
      if (block.type.startsWith(DO) && block.isEnabled()) bad.push(...outOfRange(block));
    }
    return bad;
  }

  /** Warn on fields beyond their limits (Run refuses them, and so does the server). */
  function checkLimits() {
    for (const block of workspace.getAllBlocks(false)) {
      if (!block.type.startsWith(DO)) continue;
      const bad = outOfRange(block);
      block.setWarningText(bad.length ? bad.join('\n') : null);
    }
  }

  const pre = document.getElementById('python');
  function update() {
    pre.textContent = pythonText();
    checkLimits();
  }
  workspace.addChangeListener((e) => {
    if (!e.isUiEvent) update();
  });
  update();

  document.getElementById('robot-type').textContent = config.robot_type;
  document.getElementById('bundle').textContent = config.bundle;

  // --- running -------------------------------------------------------------------------

  const status = document.getElementById('status');
  const runButton = document.getElementById('run');
  const state = { busy: false, reply: null, error: null, runs: 0 };

  function setStatus(text, kind) {
    status.textContent = text;
    status.className = kind || '';
  }

  if (served) {
    runButton.disabled = false;
  } else {
    runButton.title = "Run needs the page served: parmor blocks DIR --serve";
    setStatus('To run programs, open this page with: parmor blocks DIR --serve');
  }

  /** Post a program (an object, or a raw request body) and show the reply. */
  async function run(program) {
    if (program === undefined) {
      // the blocks' program: a value beyond its range is refused here, before it is sent
      const bad = programOutOfRange();
      if (bad.length) {
        state.error = 'not sent: ' + bad.join('; ');
        setStatus('error: ' + state.error, 'error');
        state.runs += 1;
        return { error: state.error };
      }
    }
    const text = typeof program === 'string' ? program : JSON.stringify(program || programJson());
    state.busy = true;
    runButton.disabled = true;
    setStatus('running...', 'busy');
    try {
      const response = await fetch('/run', {
        method: 'POST',
        headers: { 'Content-Type': 'application/json' },
        body: text,
      });
      let reply;
      try {
        reply = await response.json();
      } catch (e) {
        reply = { error: 'the server answered ' + response.status + ' without JSON' };
      }
      if (!response.ok || reply.error) {
        state.error = reply.error || 'the server answered ' + response.status;
        setStatus('error: ' + state.error, 'error');
      } else {
        state.error = null;
        state.reply = reply.result;
        showResult(reply.result);
        const v = reply.result.verdict;
        setStatus('done: verdict ' + (v === 'ok' ? 'ok' : 'failed (' + [].concat(v).join(', ') + ')'), 'done');
      }
    } catch (e) {
      state.error = 'no answer from the server (' + e.message + ')';
      setStatus('error: ' + state.error, 'error');
    } finally {
      state.busy = false;
      state.runs += 1;
      runButton.disabled = !served;
    }
    return state.error === null ? state.reply : { error: state.error };
  }
  runButton.addEventListener('click', () => run());

  // --- the reply: path, verdict, animation ---------------------------------------------

  const SVG = 'http://www.w3.org/2000/svg';
  function svgEl(name, attrs) {
    const el = document.createElementNS(SVG, name);
    for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
    return el;
  }

  /** The path travelled (x, y in m, seen from above, x to the right, y up). */
  function drawPath(result) {
    const box = document.getElementById('path');
    box.textContent = '';
    if (!result.final_pose) {
      const p = document.createElement('p');
      p.id = 'no-path';
      p.className = 'hint';
      p.textContent = 'This robot stands on a fixed base: it travels no path.';
      box.appendChild(p);
      return;
    }
    const xs = result.path.x.slice();
    const ys = result.path.y.slice();
    const marks = [result.expected_pose, result.final_pose].filter((p) => Array.isArray(p));
    const allx = xs.concat(marks.map((p) => p[0]), [0]);
    const ally = ys.concat(marks.map((p) => p[1]), [0]);
    let x0 = Math.min(...allx), x1 = Math.max(...allx);
    let y0 = Math.min(...ally), y1 = Math.max(...ally);
    const span = Math.max(x1 - x0, y1 - y0, 0.05);
    const pad = 0.12 * span;
    x0 -= pad; y0 -= pad; x1 += pad; y1 += pad;
    const w = Math.max(x1 - x0, 0.3 * span), h = Math.max(y1 - y0, 0.3 * span);
    const svg = svgEl('svg', { id: 'path-svg', viewBox: [x0, -(y0 + h), w, h].join(' '),
      preserveAspectRatio: 'xMidYMid meet' });
    const g = svgEl('g', { transform: 'scale(1,-1)' });
    const sw = Number((0.006 * span).toPrecision(3));
    // a 10 cm grid
    const step = Math.pow(10, Math.floor(Math.log10(span))) / (span / Math.pow(10, Math.floor(Math.log10(span))) < 3 ? 5 : 1);
    for (let gx = Math.ceil(x0 / step) * step; gx <= x0 + w; gx += step) {
      g.appendChild(svgEl('line', { x1: gx, y1: y0, x2: gx, y2: y0 + h, stroke: '#eee', 'stroke-width': sw }));
    }
    for (let gy = Math.ceil(y0 / step) * step; gy <= y0 + h; gy += step) {
      g.appendChild(svgEl('line', { x1: x0, y1: gy, x2: x0 + w, y2: gy, stroke: '#eee', 'stroke-width': sw }));
    }
    const points = xs.map((x, i) => x.toFixed(4) + ',' + ys[i].toFixed(4)).join(' ');
    g.appendChild(svgEl('polyline', { id: 'travelled', points, fill: 'none', stroke: '#1f6feb',
      'stroke-width': 2 * sw, 'data-points': xs.length }));
    const r = Number((0.02 * span).toPrecision(3));
    g.appendChild(svgEl('circle', { cx: xs.length ? xs[0] : 0, cy: ys.length ? ys[0] : 0, r, fill: '#2da44e' }));
    if (result.final_pose) {
      const [fx, fy, fyaw] = result.final_pose;
      g.appendChild(svgEl('circle', { id: 'final', cx: fx, cy: fy, r, fill: '#1f6feb' }));
      g.appendChild(svgEl('line', { x1: fx, y1: fy, x2: fx + 4 * r * Math.cos(fyaw),
        y2: fy + 4 * r * Math.sin(fyaw), stroke: '#1f6feb', 'stroke-width': sw }));
    }
    if (result.expected_pose) {
      const [ex, ey] = result.expected_pose;
      g.appendChild(svgEl('path', { id: 'expected', d: `M${ex - r},${ey - r}L${ex + r},${ey + r}M${ex - r},${ey + r}L${ex + r},${ey - r}`,
        stroke: '#cf222e', 'stroke-width': 1.5 * sw }));
    }
    svg.appendChild(g);
    box.appendChild(svg);
    const legend = document.createElement('p');
    legend.className = 'hint';
    legend.textContent = 'green: start, blue: where the robot ended, red cross: where the program says it ends; ' +
      'grid ' + short(step) + ' m';
    box.appendChild(legend);
  }

  function cell(tr, text, cls) {
    const td = document.createElement('td');
    td.textContent = text;
    if (cls) td.className = cls;
    tr.appendChild(td);
    return td;
  }

  function verdictText(v) {
    return v === 'ok' ? 'ok' : 'failed: ' + [].concat(v).join(', ');
  }

  //: the verdict figures shown in the table (the others are in the cell's tooltip)
  const MAIN_FIGURES = [
    'distance_m', 'planned_distance_m', 'heading_rad', 'planned_heading_rad',
    'final_pose_error_m', 'drift_m', 'placing_error_m', 'orientation_error_rad', 'fell',
    'max_torque_ratio', 'saturated_fraction',
  ];

  function figuresText(fig, all) {
    const keep = [];
    for (const [k, v] of Object.entries(fig || {})) {
      if (k === 'behavior' || k === 'verdict' || v === null || typeof v === 'object') continue;
      if (!all && !MAIN_FIGURES.includes(k)) continue;
      keep.push(k + ' ' + (typeof v === 'number' ? short(v) : String(v)));
    }
    return keep.join(all ? '\n' : ', ');
  }

  function pose(p) {
    return p ? 'x ' + short(p[0]) + ' m, y ' + short(p[1]) + ' m, yaw ' + short((p[2] * 180) / Math.PI) + ' deg' : '';
  }

  function drawVerdict(result) {
    const box = document.getElementById('verdict');
    box.textContent = '';
    const p = document.createElement('p');
    p.id = 'verdict-overall';
    p.className = result.verdict === 'ok' ? 'ok' : 'failed';
    p.textContent = verdictText(result.verdict);
    box.appendChild(p);
    const poses = document.createElement('p');
    poses.textContent = 'ended at ' + pose(result.final_pose) + '; the program says ' + pose(result.expected_pose);
    box.appendChild(poses);
    const table = document.createElement('table');
    table.id = 'steps';
    const head = document.createElement('tr');
    for (const h of ['#', 'behaviour', 'parameters', 'verdict', 'figures']) {
      const th = document.createElement('th');
      th.textContent = h;
      head.appendChild(th);
    }
    table.appendChild(head);
    result.steps.forEach((s, i) => {
      const tr = document.createElement('tr');
      cell(tr, String(i + 1));
      cell(tr, s.behaviour || s.behavior || '');
      cell(tr, Object.entries(s.params || {}).map(([k, v]) => k + '=' + v).join(', '));
      cell(tr, verdictText(s.verdict), s.verdict === 'ok' ? 'ok' : 'failed');
      cell(tr, figuresText(s.figures, false)).title = figuresText(s.figures, true);
      table.appendChild(tr);
    });
    box.appendChild(table);
  }

  function parseStl(THREE, buffer) {
    const view = new DataView(buffer);
    const n = buffer.byteLength >= 84 ? view.getUint32(80, true) : 0;
    const positions = [];
    if (buffer.byteLength === 84 + 50 * n) {
      for (let i = 0; i < n; i++) {
        const o = 84 + 50 * i + 12;
        for (let k = 0; k < 9; k++) positions.push(view.getFloat32(o + 4 * k, true));
      }
    } else {
      const text = new TextDecoder().decode(buffer);
      const re = /vertex\s+(\S+)\s+(\S+)\s+(\S+)/g;
      let m;
      while ((m = re.exec(text))) positions.push(Number(m[1]), Number(m[2]), Number(m[3]));
    }
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.Float32BufferAttribute(positions, 3));
    geometry.computeVertexNormals();
    return geometry;
  }

  const anim = { frame: -1, frames: 0, geoms: 0, playing: false, error: null };
  let stopAnimation = null;

  async function geometryOf(THREE, geom, meshes) {
    const t = String(geom.type).toLowerCase();
    const s = geom.size || [];
    let g = null;
    if (t === 'mesh' && geom.mesh) {
      if (!meshes.has(geom.mesh)) {
        meshes.set(geom.mesh, fetch('../' + geom.mesh).then((r) => {
          if (!r.ok) throw new Error(geom.mesh + ': ' + r.status);
          return r.arrayBuffer();
        }));
      }
      g = parseStl(THREE, await meshes.get(geom.mesh));
      if (geom.scale) g.scale(geom.scale[0], geom.scale[1], geom.scale[2]);
    } else if (t === 'box') {
      g = new THREE.BoxGeometry(2 * s[0], 2 * s[1], 2 * s[2]);
    } else if (t === 'sphere') {
      g = new THREE.SphereGeometry(s[0], 24, 16);
    } else if (t === 'ellipsoid') {
      g = new THREE.SphereGeometry(1, 24, 16);
      g.scale(s[0], s[1], s[2]);
    } else if (t === 'cylinder') {
      g = new THREE.CylinderGeometry(s[0], s[0], 2 * s[1], 24);
      g.rotateX(Math.PI / 2); // three's cylinders stand on y, MuJoCo's on z
    } else if (t === 'capsule') {
      g = new THREE.CapsuleGeometry(s[0], 2 * s[1], 8, 16);
      g.rotateX(Math.PI / 2);
    }
    return g;
  }

  async function animate(result) {
    const box = document.getElementById('robot');
    if (stopAnimation) stopAnimation();
    const a = result.animation;
    anim.frame = -1;
    anim.frames = a && a.frames ? a.frames.length : 0;
    anim.error = null;
    if (!anim.frames) {
      box.innerHTML = '<p class="hint">The reply has no animation.</p>';
      return;
    }
    let THREE;
    try {
      THREE = await import('./vendor/three.module.min.js');
    } catch (e) {
      anim.error = 'three.js did not load: ' + e.message;
      box.innerHTML = '<p class="hint"></p>';
      box.firstChild.textContent = anim.error;
      return;
    }
    let renderer;
    try {
      renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    } catch (e) {
      anim.error = 'no WebGL in this browser: ' + e.message;
      box.innerHTML = '<p class="hint"></p>';
      box.firstChild.textContent = anim.error;
      return;
    }
    box.textContent = '';
    box.appendChild(renderer.domElement);
    const width = box.clientWidth || 400, height = 240;
    renderer.setSize(width, height, false);
    renderer.setClearColor(0xf4f6f8);
    const scene = new THREE.Scene();
    scene.add(new THREE.HemisphereLight(0xffffff, 0x666677, 2.0));
    const sun = new THREE.DirectionalLight(0xffffff, 1.5);
    sun.position.set(1, -2, 3);
    scene.add(sun);
    const meshes = new Map();
    const objects = [];
    for (const geom of a.geoms) {
      const g = await geometryOf(THREE, geom, meshes);
      if (!g) { objects.push(null); continue; }
      const rgba = geom.rgba || [0.7, 0.7, 0.7, 1];
      const material = new THREE.MeshStandardMaterial({
        color: new THREE.Color(rgba[0], rgba[1], rgba[2]),
        transparent: rgba[3] < 1, opacity: rgba[3], roughness: 0.7,
      });
      const mesh = new THREE.Mesh(g, material);
      scene.add(mesh);
      objects.push(mesh);
    }
    anim.geoms = objects.filter(Boolean).length;
    // the camera looks at where the robot goes, from the side, z up as in MuJoCo
    const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (const f of a.frames) for (const p of f.pos) for (let k = 0; k < 3; k++) {
      lo[k] = Math.min(lo[k], p[k]); hi[k] = Math.max(hi[k], p[k]);
    }
    const c = lo.map((l, k) => (l + hi[k]) / 2);
    const ext = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 0.1);
    const grid = new THREE.GridHelper(Math.ceil(4 * ext * 10) / 10, 20, 0x999999, 0xcccccc);
    grid.rotateX(Math.PI / 2);
    grid.position.set(c[0], c[1], 0);
    scene.add(grid);
    if (result.path && result.path.x.length > 1) {
      const pts = result.path.x.map((x, i) => new THREE.Vector3(x, result.path.y[i], 0.001));
      scene.add(new THREE.Line(new THREE.BufferGeometry().setFromPoints(pts),
        new THREE.LineBasicMaterial({ color: 0x1f6feb })));
    }
    const camera = new THREE.PerspectiveCamera(40, width / height, 0.01, 100);
    camera.up.set(0, 0, 1);
    camera.position.set(c[0] + 0.9 * ext, c[1] - 1.3 * ext, c[2] + 0.8 * ext);
    camera.lookAt(c[0], c[1], c[2]);
    const fps = a.fps || 30;
    let stopped = false;
    const t0 = performance.now();
    function show(i) {
      const f = a.frames[i];
      objects.forEach((o, k) => {
        if (!o) return;
        const p = f.pos[k], q = f.quat[k];
        o.position.set(p[0], p[1], p[2]);
        o.quaternion.set(q[1], q[2], q[3], q[0]);
      });
      renderer.render(scene, camera);
      anim.frame = i;
    }
    function tick() {
      if (stopped) return;
      const i = Math.floor(((performance.now() - t0) / 1000) * fps) % a.frames.length;
      if (i !== anim.frame) show(i);
      requestAnimationFrame(tick);
    }
    show(0);
    anim.playing = true;
    requestAnimationFrame(tick);
    stopAnimation = () => {
      stopped = true;
      anim.playing = false;
      renderer.dispose();
    };
  }

  function showResult(result) {
    drawPath(result);
    drawVerdict(result);
    animate(result).catch((e) => {
      anim.error = String(e);
    });
  }

  // what tests and curious users can reach from the console
  window.parmor = {
    workspace, programJson, python: pythonText, run, state, animation: anim, pyNumber, served,
  };
})();
