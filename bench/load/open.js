// Open loop: requests arrive at a fixed rate (k6 constant-arrival-rate), one phase after another,
// whatever the server's speed. Each request is `POST /v1/voxelize?resolution=R` without `wait`
// (202 Accepted + the job's id); the virtual user then polls `GET /v1/jobs/{id}` (after 10 ms,
// doubling to at most 250 ms) until the job is final or POLL_S have passed since the POST.
// Accepted ids and final states go to the console log (`A <id>` / `F <id> <state>`) for
// report.py's sweep, which checks at the end that every accepted job succeeded.
//
// Environment: BASE, CLASSES (see lib.js), PHASES (JSON list of {name, rate (requests/s),
// duration (s), vus, max_vus}), POLL_S (60), SUMMARY (path of the JSON summary).

import http from 'k6/http';
import exec from 'k6/execution';
import { sleep } from 'k6';
import { Counter, Trend } from 'k6/metrics';
import {
  BASE, loadClasses, pick, statusCounters, countStatus, retryAfterMetrics, checkRetryAfter,
  logUnexpected, TREND_STATS, AUTH } from './lib.js';

const classes = loadClasses();
const phases = JSON.parse(__ENV.PHASES);
const POLL_S = Number(__ENV.POLL_S || 60);
const FINAL = { succeeded: true, failed: true, canceled: true };

const scenarios = {};
let start = 0;
for (const p of phases) {
  scenarios[p.name] = {
    executor: 'constant-arrival-rate',
    exec: 'job',
    rate: p.rate,
    timeUnit: '1s',
    duration: `${p.duration}s`,
    startTime: `${start}s`,
    preAllocatedVUs: p.vus,
    maxVUs: p.max_vus,
    gracefulStop: `${POLL_S + 5}s`,
  };
  start += p.duration;
}

export const options = { scenarios, summaryTrendStats: TREND_STATS };

// Per phase: statuses of the POSTs, Retry-After, POST latency (all, and the 429s alone), and per
// class: accepted, refused, client-seen time to the final state, and the server's own
// queued_s + running_s of the job.
const M = {};
for (const p of phases) {
  const n = p.name;
  const m = {
    st: statusCounters(`st_${n}_`),
    ra: retryAfterMetrics(`${n}_`),
    post: new Trend(`post_ms_${n}`, true),
    post429: new Trend(`post429_ms_${n}`, true),
    final: {
      succeeded: new Counter(`final_${n}_succeeded`),
      failed: new Counter(`final_${n}_failed`),
      canceled: new Counter(`final_${n}_canceled`),
    },
    lostTimeout: new Counter(`lost_${n}_timeout`),
    pollErr: new Counter(`poll_err_${n}`),
    done: new Trend(`done_ms_${n}`, true),
    srv: new Trend(`srv_ms_${n}`, true),
    byClass: {},
  };
  for (const c of classes) {
    m.byClass[c.name] = {
      acc: new Counter(`acc_${n}_${c.name}`),
      rej: new Counter(`rej_${n}_${c.name}`),
      done: new Trend(`done_ms_${n}_${c.name}`, true),
      srv: new Trend(`srv_ms_${n}_${c.name}`, true),
    };
  }
  M[n] = m;
}

export function setup() {
  console.log(`START ${Date.now()}`);
}

export function job() {
  const m = M[exec.scenario.name];
  const c = pick(classes);
  const t0 = Date.now();
  const res = http.post(`${BASE}/v1/voxelize?resolution=${c.res}`, c.body, {
    headers: { 'Content-Type': c.ctype, ...AUTH },
    timeout: '60s',
    tags: { name: 'voxelize', cls: c.name },
  });
  countStatus(m.st, res.status);
  m.post.add(res.timings.duration);
  if (res.status === 429) {
    m.post429.add(res.timings.duration);
    m.byClass[c.name].rej.add(1);
    checkRetryAfter(m.ra, res);
    return;
  }
  if (res.status !== 202) {
    m.byClass[c.name].rej.add(1);
    logUnexpected('voxelize', res);
    return;
  }
  m.byClass[c.name].acc.add(1);
  const id = res.json('id');
  console.log(`A ${id}`);
  let delay = 0.01;
  const deadline = t0 + POLL_S * 1000;
  while (Date.now() < deadline) {
    sleep(delay);
    delay = Math.min(delay * 2, 0.25);
    const g = http.get(`${BASE}/v1/jobs/${id}`, { headers: AUTH, timeout: '30s', tags: { name: 'job' } });
    if (g.status !== 200) {
      m.pollErr.add(1);
      logUnexpected('poll', g);
      continue;
    }
    const j = g.json();
    if (!FINAL[j.state]) continue;
    const t = Date.now() - t0;
    console.log(`F ${id} ${j.state}`);
    m.final[j.state].add(1);
    if (j.state === 'succeeded') {
      m.done.add(t);
      m.byClass[c.name].done.add(t);
      const s = 1000 * ((j.timings.queued_s || 0) + (j.timings.running_s || 0));
      m.srv.add(s);
      m.byClass[c.name].srv.add(s);
    }
    return;
  }
  m.lostTimeout.add(1);
}

export function handleSummary(data) {
  const out = {};
  out[__ENV.SUMMARY || 'summary.json'] = JSON.stringify(data, null, 1);
  let line = '';
  for (const p of phases) {
    const v = (k) => (data.metrics[k] ? data.metrics[k].values.count : 0);
    const d = data.metrics[`done_ms_${p.name}`];
    line += `  ${p.name} @ ${p.rate}/s: 202 ${v(`st_${p.name}_202`)}, 429 ${v(`st_${p.name}_429`)}, ` +
      `succeeded ${v(`final_${p.name}_succeeded`)}` +
      (d ? `, done p50 ${d.values.med.toFixed(0)} p99 ${d.values['p(99)'].toFixed(0)} ms` : '') + '\n';
  }
  out.stdout = line;
  return out;
}
