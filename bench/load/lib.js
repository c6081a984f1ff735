// Shared by closed.js and open.js (k6 v1.1.0 scripts for bench/load/run.sh).
//
// CLASSES (environment, JSON): the request classes, each {name, mesh (absolute path), res,
// weight, ctype?}; a request picks one at random by weight. Meshes are read once per VU in the
// init context (k6's open()).

import { Counter, Trend } from 'k6/metrics';

export const BASE = __ENV.BASE || 'http://127.0.0.1:8080';

// API_KEY (environment): sent as `Authorization: Bearer KEY` on every request, for a server
// started with --api-keys-file (unset: no header).
export const AUTH = __ENV.API_KEY ? { Authorization: `Bearer ${__ENV.API_KEY}` } : {};

// HTTP statuses counted one by one; anything else lands in `other`. 0 is a transport error
// (connection refused or reset, timeout).
export const STATUSES = [0, 200, 201, 202, 400, 404, 408, 413, 415, 422, 429, 500, 502, 503, 504, 507];

export function loadClasses() {
  const spec = JSON.parse(__ENV.CLASSES);
  let total = 0;
  const bodies = {}; // one copy per mesh file and VU, however many classes use it
  const classes = spec.map((c) => {
    if (!(c.mesh in bodies)) bodies[c.mesh] = open(c.mesh, 'b');
    total += c.weight;
    return {
      name: c.name,
      res: c.res,
      weight: c.weight,
      upto: total,
      ctype: c.ctype || 'model/obj',
      body: bodies[c.mesh],
    };
  });
  classes.forEach((c) => { c.upto /= total; });
  return classes;
}

export function pick(classes) {
  const r = Math.random();
  for (const c of classes) {
    if (r < c.upto) return c;
  }
  return classes[classes.length - 1];
}

// One counter per status, under a prefix (`st_` or `st_<phase>_`).
export function statusCounters(prefix) {
  const m = {};
  for (const s of STATUSES) m[s] = new Counter(`${prefix}${s}`);
  m.other = new Counter(`${prefix}other`);
  return m;
}

export function countStatus(counters, status) {
  (counters[status] || counters.other).add(1);
}

// Retry-After on a 429: present and a whole number of seconds (RFC 9110 delay-seconds).
export function retryAfterMetrics(prefix) {
  return { value: new Trend(`${prefix}retry_after_s`), bad: new Counter(`${prefix}retry_after_bad`) };
}

export function checkRetryAfter(m, res) {
  const v = res.headers['Retry-After'];
  if (v === undefined || !/^[0-9]+$/.test(v)) {
    m.bad.add(1);
    return false;
  }
  m.value.add(Number(v));
  return true;
}

let logged = 0;
// The first few unexpected answers go to the console log (k6 --console-output), body cut short.
export function logUnexpected(what, res) {
  if (logged >= 20) return;
  logged += 1;
  const body = typeof res.body === 'string' ? res.body.slice(0, 300) : '';
  console.log(`UNEXPECTED ${what} status=${res.status} error=${res.error || ''} body=${body}`);
}

export const TREND_STATS = ['min', 'med', 'avg', 'p(90)', 'p(95)', 'p(99)', 'max', 'count'];
