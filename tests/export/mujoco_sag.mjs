// rodfit's MuJoCo export loaded in MuJoCo (its WebAssembly build, npm mujoco-js, MuJoCo 3.3) and
// its static sag compared with rodfit's (docs/formats.md, "Exports", mujoco).
//
// The WebAssembly build has no plugins, so the cable's elasticity plugin is replaced by what it
// computes for planar bending: the plugin's moment between consecutive bodies is -E I omega / l
// (plugin/elasticity/cable.cc), a ball joint's spring -k omega (omega the rotation vector from
// the spring's reference), so the joint stiffness k = E I / l with the file's own bend = E, the
// capsule's I = pi r^4 / 4 and l the distance between the two bodies' origins (l / 2 for the
// first joint, against the clamp's half-segment body). The spring's reference is the straight
// cable (the plugin's flat="true"). Everything else (vertices, masses, gravity, the clamp) is the
// exported file's. Checked: the tip's sag after settling, from the exported start (rodfit's held
// equilibrium) and from the straight rod, within 1 % of rodfit's sag at 60 segments. Not checked:
// the plugin itself (not in this build), twist (planar case), dynamics (the test adds
// stiffness-proportional joint damping to settle, and its own time step).
//
// Usage: node mujoco_sag.mjs RODFIT_CLI PROFILE WORK_DIR   (exit 0 pass, 1 fail, 77 skip)
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';

const [cli, profilePath, work] = process.argv.slice(2);
let loadMujoco;
try {
  loadMujoco = (await import('mujoco-js')).default;
} catch (e) {
  console.log('SKIP: npm mujoco-js is not installed (scripts/install_deps.sh installs it)');
  process.exit(77);
}

// A cantilever: the bundled suture's rod at 60 segments, isotropic, sagging ~20 % of its length
// under its own weight (q L^3 / B = 1.76: well into the nonlinear range).
const profile = JSON.parse(fs.readFileSync(profilePath, 'utf8'));
profile.rod.segments = 60;
profile.parameters.bend_stiffness.value = 1e-5;
profile.parameters.bend_stiffness_2.value = 1e-5;
fs.mkdirSync(work, { recursive: true });
const cantilever = path.join(work, 'cantilever.json');
fs.writeFileSync(cantilever, JSON.stringify(profile, null, 1));
const mjcf = path.join(work, 'cantilever.xml');
execFileSync(cli, ['export', cantilever, '--format', 'mujoco', '-o', mjcf]);
const text = fs.readFileSync(mjcf, 'utf8');

const attr = (element, name) => {
  const m = element.match(new RegExp(`\\b${name}="([^"]*)"`));
  if (!m) throw new Error(`no ${name} in ${element}`);
  return m[1];
};
const composite = text.match(/<composite [^>]*>/)[0];
const vertex = attr(composite, 'vertex').trim().split(/\s+/).map(Number);
const E = Number(attr(text.match(/<config key="bend"[^>]*>/)[0], 'value'));
const radius = Number(attr(text.match(/<geom [^>]*>/)[0], 'size'));
const n = vertex.length / 3 - 2;  // the clamp's half-segment body, then n + 1 rod vertices
const l = Math.hypot(vertex[6] - vertex[3], vertex[7] - vertex[4], vertex[8] - vertex[5]);
const k = E * Math.PI * radius ** 4 / 4 / l;  // the plugin's E I / l
// rodfit's equilibrium: the exported start shape's tip relative to the clamp (vertex 0).
const rodfitSag = vertex[3 * (n + 1) + 2] - vertex[5];
const rodfitReach = vertex[3 * (n + 1)] - vertex[3];

const mujoco = await loadMujoco();
mujoco.FS.mkdir('/w');

// The exported file with the plugin replaced by joint springs (and settling damping), started
// from `start` (flat xyz of the n + 2 cable vertices).
function settle(start) {
  const tau = 0.05;  // [s] stiffness-proportional damping: the slowest mode's ratio ~0.5
  let xml = text.replace(/<extension>[\s\S]*?<\/extension>/, '')
      .replace(/<plugin plugin="mujoco.elasticity.cable">[\s\S]*?<\/plugin>/, '')
      .replace(/<joint kind="main"[^>]*\/>/, `<joint kind="main" stiffness="${k}" damping="${tau * k}"/>`)
      .replace(/vertex="[^"]*"/, `vertex="${start.join(' ')}"`)
      .replace(/timestep="[^"]*"/, 'timestep="2e-4"');
  mujoco.FS.writeFile('/w/cable.xml', xml);
  const model = mujoco.MjModel.loadFromXML('/w/cable.xml');
  const data = new mujoco.MjData(model);
  // The first joint (body B_1 against the clamp's half segment) is twice as stiff; every spring's
  // reference is the straight cable: the inverse of the body's rest rotation in its parent.
  const stiffness = model.jnt_stiffness;
  stiffness[0] = 2 * k;
  const damping = model.dof_damping;
  for (let d = 0; d < 3; ++d) damping[d] = 2 * tau * k;
  const spring = model.qpos_spring, bodyQuat = model.body_quat, jntBody = model.jnt_bodyid;
  const adr = model.jnt_qposadr;
  for (let j = 0; j < model.njnt; ++j) {
    const b = jntBody[j];
    spring[adr[j]] = bodyQuat[4 * b];
    for (let c = 1; c < 4; ++c) spring[adr[j] + c] = -bodyQuat[4 * b + c];
  }
  let last = null, tip = null;
  for (let step = 1; step <= 30000; ++step) {
    mujoco.mj_step(model, data);
    if (step % 2500 === 0) {
      const x = data.site_xpos;  // sites: S_first (the clamp body's start), S_last (the tip)
      tip = [x[3], x[4], x[5]];
      if (last && Math.abs(tip[2] - last[2]) < 1e-7) break;
      last = tip;
    }
  }
  const clamp = [vertex[3], vertex[4], vertex[5]];
  data.delete();
  model.delete();
  return { sag: tip[2] - clamp[2], reach: tip[0] - clamp[0] };
}

const straight = [vertex[0], vertex[1], vertex[2]];
for (let i = 0; i <= n; ++i) straight.push(vertex[3] + i * l, vertex[4], vertex[5]);
let failed = 0;
for (const [name, start] of [['from rodfit\'s equilibrium', vertex], ['from the straight rod', straight]]) {
  const { sag, reach } = settle(start);
  const error = Math.abs(sag - rodfitSag) / Math.abs(rodfitSag);
  const ok = error < 0.01;
  failed += ok ? 0 : 1;
  console.log(`${ok ? 'ok' : 'FAIL'}: ${n} segments, ${name}: MuJoCo sag ${sag.toFixed(6)} m, ` +
              `reach ${reach.toFixed(6)} m; rodfit ${rodfitSag.toFixed(6)} m, ` +
              `${rodfitReach.toFixed(6)} m; sag error ${(100 * error).toFixed(3)} % (limit 1 %)`);
}
console.log(`${2 - failed} passed, ${failed} failed`);
process.exit(failed ? 1 : 0);
