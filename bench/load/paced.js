// Paced: requests arrive at RATE per second (k6 constant-arrival-rate) from at most VUS virtual
// users (16: "16 concurrent clients"), each `POST /v1/voxelize?resolution=R&wait=WAIT`, so the
// latency of a 201 is the time to the finished job, measured below saturation (RATE is set
// under the closed-loop capacity). Arrivals that find all VUS busy are dropped by k6 and counted
// (dropped_iterations): a sign the rate was not below saturation after all.
//
// Environment: BASE, CLASSES (see lib.js), RATE, VUS (16), DURATION (e.g. 15s), WAIT (30),
// SUMMARY.

import http from 'k6/http';
import { Trend } from 'k6/metrics';
import {
  BASE, loadClasses, pick, statusCounters, countStatus, retryAfterMetrics, checkRetryAfter,
  logUnexpected, TREND_STATS, AUTH } from './lib.js';

const classes = loadClasses();
const WAIT = __ENV.WAIT || '30';
const VUS = Number(__ENV.VUS || 16);

export const options = {
  scenarios: {
    paced: {
      executor: 'constant-arrival-rate',
      rate: Number(__ENV.RATE),
      timeUnit: '1s',
      duration: __ENV.DURATION || '15s',
      preAllocatedVUs: VUS,
      maxVUs: VUS,
      gracefulStop: '35s',
    },
  },
  summaryTrendStats: TREND_STATS,
};

const st = statusCounters('st_');
const ra = retryAfterMetrics('');
const ok = new Trend('ok_ms', true);

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
  } else if (res.status === 429) {
    checkRetryAfter(ra, res);
  } else {
    logUnexpected('voxelize', res);
  }
}

export function handleSummary(data) {
  const out = {};
  out[__ENV.SUMMARY || 'summary.json'] = JSON.stringify(data, null, 1);
  const n = data.metrics.st_201 ? data.metrics.st_201.values.count : 0;
  const d = data.metrics.dropped_iterations ? data.metrics.dropped_iterations.values.count : 0;
  const secs = data.state.testRunDurationMs / 1000;
  const p = data.metrics.ok_ms ? data.metrics.ok_ms.values : {};
  out.stdout = `  @ ${__ENV.RATE}/s: 201: ${n} in ${secs.toFixed(1)} s = ${(n / secs).toFixed(1)} jobs/s; ` +
    `p50 ${(p.med || 0).toFixed(1)} p95 ${(p['p(95)'] || 0).toFixed(1)} p99 ${(p['p(99)'] || 0).toFixed(1)} ms; dropped ${d}\n`;
  return out;
}
