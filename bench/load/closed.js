// Closed loop: VUS virtual users, each sending `POST /v1/voxelize?resolution=R&wait=WAIT` back to
// back for DURATION, so every request returns the finished job (201 Created) unless the job
// takes longer than WAIT (202). jobs/s = 201s per second of the run.
//
// Environment: BASE, CLASSES (see lib.js), VUS, DURATION (k6 duration, e.g. 15s), WAIT (s, 30),
// SUMMARY (path of the JSON summary written by handleSummary).

import http from 'k6/http';
import { sleep } from 'k6';
import { Trend } from 'k6/metrics';
import {
  BASE, loadClasses, pick, statusCounters, countStatus, retryAfterMetrics, checkRetryAfter,
  logUnexpected, TREND_STATS, AUTH } from './lib.js';

const classes = loadClasses();
const WAIT = __ENV.WAIT || '30';

export const options = {
  scenarios: {
    closed: {
      executor: 'constant-vus',
      vus: Number(__ENV.VUS || 1),
      duration: __ENV.DURATION || '15s',
      gracefulStop: '35s',
    },
  },
  summaryTrendStats: TREND_STATS,
  // The default thresholds-free run; the verdict is computed by report.py.
};

const st = statusCounters('st_');
const ra = retryAfterMetrics('');
// Latency of the requests answered 201 (the job done), in ms, overall and per class.
const ok = new Trend('ok_ms', true);
const okBy = {};
for (const c of classes) okBy[c.name] = new Trend(`ok_ms_${c.name}`, true);

export default function () {
  const c = pick(classes);
  const res = http.post(`${BASE}/v1/voxelize?resolution=${c.res}&wait=${WAIT}`, c.body, {
    headers: { 'Content-Type': c.ctype, ...AUTH },
    timeout: '120s',
    tags: { name: 'voxelize', cls: c.name },
  });
  countStatus(st, res.status);
  if (res.status === 201) {
    ok.add(res.timings.duration);
    okBy[c.name].add(res.timings.duration);
    return;
  }
  if (res.status === 429) {
    checkRetryAfter(ra, res);
  } else {
    logUnexpected('voxelize', res);
  }
  // Back off on refusals and errors so a failing server is not hammered in a tight loop.
  sleep(0.05);
}

export function handleSummary(data) {
  const out = {};
  out[__ENV.SUMMARY || 'summary.json'] = JSON.stringify(data, null, 1);
  const n = data.metrics.st_201 ? data.metrics.st_201.values.count : 0;
  const secs = data.state.testRunDurationMs / 1000;
  const p = data.metrics.ok_ms ? data.metrics.ok_ms.values : {};
  out.stdout = `  201: ${n} in ${secs.toFixed(1)} s = ${(n / secs).toFixed(1)} jobs/s; ` +
    `p50 ${(p.med || 0).toFixed(1)} p95 ${(p['p(95)'] || 0).toFixed(1)} p99 ${(p['p(99)'] || 0).toFixed(1)} ms\n`;
  return out;
}
