#!/usr/bin/env python3
"""Results of a bench/load/run.sh run: results.json, results.md and load-*.png in OUT_DIR.

Reads machine.json, servers.jsonl, steps.jsonl, every step's k6 summary (*.k6.json), the
sampler's CSVs (*.samples.csv) and the sweeps (*.sweep.json). Needs matplotlib (the run's venv).

CPU shares per step: the server's CPU time (from /proc/PID/stat, interpolated from the samples
at the step's start and end), k6's (bash `time` around it) and "other" = the whole machine's
busy time minus those two (other processes: the sampler, other users' builds), each divided by
the step's wall time, in cores (the machine has two).
"""

import bisect
import csv
import glob
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

FINAL = ("succeeded", "failed", "canceled")


def probes(rows, key):
    """Summary of a probe's samples (ms, -1: failed): max, p50, failures, count; None without any."""
    v = sorted(r[key] for r in rows if r[key] is not None)
    if not v:
        return None
    return {"max": round(v[-1], 1), "p50": round(v[len(v) // 2], 1),
            "failed": sum(1 for x in v if x < 0), "samples": len(v)}


def load_samples(path):
    rows = []
    with open(path) as f:
        for r in csv.DictReader(f):
            def num(k):
                v = r.get(k, "")
                return float(v) if v not in ("", None) else None
            rows.append({
                "t": float(r["t"]), "phase": r["phase"], "depth": num("queue_depth"),
                "running": num("queue_running"), "finished": num("jobs_finished"),
                "healthz_ms": num("healthz_ms"), "metrics_ms": num("metrics_ms"),
                "rss_mib": num("rss_kib") / 1024, "hwm_mib": num("hwm_kib") / 1024,
                "threads": num("threads"), "fds": num("fds"), "cpu": num("server_cpu_s"),
                "busy": num("machine_busy_s"), "probe_ms": num("probe_fsync_ms"), "overflows": num("listen_overflows"),
                "admin_healthz_ms": num("admin_healthz_ms"),
            })
    return rows


def interp(rows, key, t):
    ts = [r["t"] for r in rows]
    i = bisect.bisect_left(ts, t)
    pts = [r for r in rows[max(0, i - 1):i + 1] if r[key] is not None]
    if not pts:
        return None
    if len(pts) == 1 or pts[1]["t"] == pts[0]["t"]:
        return pts[0][key]
    a, b = pts
    f = min(1.0, max(0.0, (t - a["t"]) / (b["t"] - a["t"])))
    return a[key] + f * (b[key] - a[key])


def window(rows, t0, t1):
    return [r for r in rows if t0 <= r["t"] <= t1]


def count(k6, name):
    m = k6["metrics"].get(name)
    return int(m["values"]["count"]) if m else 0


def trend(k6, name):
    m = k6["metrics"].get(name)
    if not m or not m["values"].get("count"):
        return None
    v = m["values"]
    return {"p50": v["med"], "p90": v["p(90)"], "p95": v["p(95)"], "p99": v["p(99)"],
            "max": v["max"], "avg": v["avg"], "count": int(v["count"])}


def statuses(k6, prefix):
    out = {}
    for name, m in k6["metrics"].items():
        if name.startswith(prefix) and m["type"] == "counter":
            code = name[len(prefix):]
            if code.isdigit() or code == "other":
                out[code] = int(m["values"]["count"])
    return dict(sorted(out.items()))


def cpu_shares(samples, step):
    t0, t1 = step["start"], step["end"]
    wall = t1 - t0
    s0, s1 = interp(samples, "cpu", t0), interp(samples, "cpu", t1)
    b0, b1 = interp(samples, "busy", t0), interp(samples, "busy", t1)
    k6 = step["k6_user_s"] + step["k6_sys_s"]
    server = (s1 - s0) if s0 is not None and s1 is not None else None
    busy = (b1 - b0) if b0 is not None and b1 is not None else None
    other = busy - server - k6 if busy is not None and server is not None else None
    r = lambda x: round(x / wall, 2) if x is not None else None  # noqa: E731
    return {"server_cores": r(server), "k6_cores": r(k6), "other_cores": r(other),
            "machine_cores": r(busy)}


def delta(rows, key, t0, t1, per_s=True):
    a, b = interp(rows, key, t0), interp(rows, key, t1)
    if a is None or b is None:
        return None
    return round((b - a) / (t1 - t0), 2) if per_s else int(round(b - a))


def median(xs):
    xs = sorted(xs)
    return round(xs[len(xs) // 2], 2) if xs else None


def fmt(x, nd=1):
    if x is None:
        return "–"
    if isinstance(x, float):
        return f"{x:,.{nd}f}"
    return f"{x:,}"


def main():
    out = sys.argv[1]
    machine = json.load(open(os.path.join(out, "machine.json")))
    servers = {}
    for line in open(os.path.join(out, "servers.jsonl")):
        s = json.loads(line)
        servers[s["name"]] = s
    steps = [json.loads(line) for line in open(os.path.join(out, "steps.jsonl"))]
    samples = {n: load_samples(os.path.join(out, f"{n}.samples.csv")) for n in servers}
    res = {"machine": machine, "servers": servers, "closed": [], "paced": [], "open": [], "sweeps": {}}

    for st in steps:
        name = f"{st['scenario']}-{st['step']}"
        path = os.path.join(out, f"{name}.k6.json")
        if not os.path.exists(path):
            continue
        k6 = json.load(open(path))
        sm = samples[st["server"]]
        cpu = cpu_shares(sm, st)
        if st["script"] in ("closed.js", "paced.js"):
            secs = k6["state"]["testRunDurationMs"] / 1000
            n201 = count(k6, "st_201")
            w = window(sm, st["start"], st["end"])
            paced = st["script"] == "paced.js"
            res["paced" if paced else "closed"].append({
                "scenario": st["scenario"], "step": st["step"],
                "rate": int(st["args"].split("RATE=")[1].split()[0]) if paced else None,
                "dropped_iterations": count(k6, "dropped_iterations"),
                "store": servers[st["server"]]["fs"],
                "workers": int(servers[st["server"]]["args"].split("--workers ")[1].split()[0]),
                "classes": [c["name"] for c in st["classes"]],
                "vus": int(st["args"].split("VUS=")[1].split()[0]),
                "seconds": round(secs, 2), "created_201": n201,
                "jobs_per_s": round(n201 / secs, 1),
                "latency_ms": trend(k6, "ok_ms"),
                "statuses": statuses(k6, "st_"),
                "retry_after_bad": count(k6, "retry_after_bad"),
                "max_queue_depth": max((r["depth"] or 0 for r in w), default=None),
                "max_rss_mib": round(max((r["rss_mib"] for r in w), default=0), 1),
                "healthz_max_ms": round(max((r["healthz_ms"] for r in w), default=0), 1),
                "disk_probe_ms_p50": median([r["probe_ms"] for r in w if r.get("probe_ms") is not None]),
                "stalls_0_5s": sum(1 for a, b in zip(w, w[1:]) if a["finished"] is not None and b["finished"] == a["finished"] and (a["depth"] or 0) > 0),
                "cpu": cpu, "loadavg": [st["loadavg_start"], st["loadavg_end"]],
            })
            continue
        # open.js: phases one after another from the START line of the console log.
        phases = json.loads(st["args"].split("PHASES=", 1)[1].rsplit(" -e ", 1)[0])
        start = None
        for line in open(os.path.join(out, f"{name}.console.log"), errors="replace"):
            if 'msg="START ' in line:
                start = int(line.split('msg="START ')[1].split('"')[0]) / 1000
        t = start or st["start"]
        for p in phases:
            n = p["name"]
            t0, t1 = t, t + p["duration"]
            t = t1
            w = window(sm, t0, t1)
            f0, f1 = interp(sm, "finished", t0), interp(sm, "finished", t1)
            by_class = {}
            for c in st["classes"]:
                cn = c["name"]
                by_class[cn] = {
                    "res": c["res"], "weight": c["weight"],
                    "accepted": count(k6, f"acc_{n}_{cn}"), "refused": count(k6, f"rej_{n}_{cn}"),
                    "done_ms": trend(k6, f"done_ms_{n}_{cn}"),
                    "server_ms": trend(k6, f"srv_ms_{n}_{cn}"),
                }
            sts = statuses(k6, f"st_{n}_")
            res["open"].append({
                "scenario": st["scenario"], "phase": n, "offered_per_s": p["rate"],
                "seconds": p["duration"],
                "server_args": servers[st["server"]]["args"],
                "requests": sum(sts.values()), "statuses": sts,
                "accepted_per_s": round(sts.get("202", 0) / p["duration"], 1),
                "completed_per_s": round((f1 - f0) / p["duration"], 1) if f0 is not None and f1 is not None else None,
                "final": {s: count(k6, f"final_{n}_{s}") for s in FINAL},
                "lost_poll_timeout": count(k6, f"lost_{n}_timeout"),
                "poll_errors": count(k6, f"poll_err_{n}"),
                "retry_after_s": trend(k6, f"{n}_retry_after_s"),
                "retry_after_bad": count(k6, f"{n}_retry_after_bad"),
                "post_ms": trend(k6, f"post_ms_{n}"), "post429_ms": trend(k6, f"post429_ms_{n}"),
                "done_ms": trend(k6, f"done_ms_{n}"), "server_ms": trend(k6, f"srv_ms_{n}"),
                "by_class": by_class,
                "max_queue_depth": max((r["depth"] or 0 for r in w), default=None),
                "max_running": max((r["running"] or 0 for r in w), default=None),
                "max_rss_mib": round(max((r["rss_mib"] for r in w), default=0), 1),
                "healthz_ms": probes(w, "healthz_ms"),
                "admin_healthz_ms": probes(w, "admin_healthz_ms"),
                "dropped_iterations": count(k6, "dropped_iterations"),
                "phase_server_cores": delta(sm, "cpu", t0, t1),
                "phase_machine_cores": delta(sm, "busy", t0, t1),
                "listen_overflows": delta(sm, "overflows", t0, t1, per_s=False),
                "max_fds": int(max((r["fds"] for r in w), default=0)),
                "max_threads": int(max((r["threads"] for r in w), default=0)),
                "cpu_whole_run": cpu, "loadavg": [st["loadavg_start"], st["loadavg_end"]],
            })
        sw = os.path.join(out, f"{name}.sweep.json")
        if os.path.exists(sw):
            res["sweeps"][st["scenario"]] = json.load(open(sw))

    for n, sm in samples.items():
        if sm:
            servers[n]["peak_rss_mib"] = round(max(r["hwm_mib"] for r in sm), 1)
            servers[n]["end_rss_mib"] = round(sm[-1]["rss_mib"], 1)
            servers[n]["max_fds"] = int(max(r["fds"] for r in sm))
            servers[n]["max_threads"] = int(max(r["threads"] for r in sm))
            for key, name in (("healthz_ms", "healthz"), ("admin_healthz_ms", "admin_healthz")):
                p = probes(sm, key) or {}
                servers[n][f"{name}_max_ms"] = p.get("max")
                servers[n][f"{name}_failed"] = p.get("failed")

    json.dump(res, open(os.path.join(out, "results.json"), "w"), indent=1)
    write_md(out, res)
    plots(out, res, samples, steps)
    return 0


def write_md(out, res):
    m = res["machine"]
    L = []
    L.append(f"voxd: `{m['voxd_bin']}` ({m['voxd_version']}), git {m['git']}; {m['k6']}")
    L.append(f"machine: {m['cpu']}, {m['memory_gib']} GiB, {m['kernel']}; data dir {m['data_dir_fs']}; "
             f"--workers {m['workers']}")
    L.append(f"load average: start {m['loadavg_start']}, end {m.get('loadavg_end', '?')}")
    for k in ("fsync_probe_start", "fsync_probe_end"):
        if k in m:
            L.append(f"durable 1 KiB write ({k[12:]}): disk p50 {m[k]['disk']['p50_ms']} ms (p90 {m[k]['disk']['p90_ms']}), "
                     f"tmpfs p50 {m[k]['tmpfs']['p50_ms']} ms")
    L.append("")
    if res["closed"]:
        L.append("| store | workers | mesh | users | jobs/s | p50 ms | p95 ms | p99 ms | max ms | non-201 | server / k6 / other CPU (cores) | disk write ms (p50) | stalls | load avg |")
        L.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for r in res["closed"]:
            lat = r["latency_ms"] or {}
            non = {k: v for k, v in r["statuses"].items() if k != "201"}
            c = r["cpu"]
            label = f"{r['classes'][0]} 64³" if len(r['classes']) == 1 else "mix (calibration)"
            L.append(f"| {r['store']} | {r['workers']} | {label} | {r['vus']} | {fmt(r['jobs_per_s'])} | "
                     f"{fmt(lat.get('p50'))} | {fmt(lat.get('p95'))} | {fmt(lat.get('p99'))} | {fmt(lat.get('max'))} | "
                     f"{', '.join(f'{k}: {v}' for k, v in non.items()) or '0'} | "
                     f"{fmt(c['server_cores'], 2)} / {fmt(c['k6_cores'], 2)} / {fmt(c['other_cores'], 2)} | {fmt(r['disk_probe_ms_p50'], 2)} | {r['stalls_0_5s']} | {r['loadavg'][0]} → {r['loadavg'][1]} |")
        L.append("")
    if res["paced"]:
        L.append("Paced (16 users, arrivals at a fixed rate below the 16-user closed-loop jobs/s, `wait=30`):")
        L.append("")
        L.append("| store | mesh | offered/s | jobs/s | p50 ms | p95 ms | p99 ms | max ms | dropped arrivals | non-201 | server / k6 / other CPU (cores) | disk write ms (p50) |")
        L.append("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for r in res["paced"]:
            lat = r["latency_ms"] or {}
            non = {k: v for k, v in r["statuses"].items() if k != "201"}
            c = r["cpu"]
            L.append(f"| {r['store']} | {r['classes'][0]} 64³ | {r['rate']} | {fmt(r['jobs_per_s'])} | "
                     f"{fmt(lat.get('p50'))} | {fmt(lat.get('p95'))} | {fmt(lat.get('p99'))} | {fmt(lat.get('max'))} | {r['dropped_iterations']} | "
                     f"{', '.join(f'{k}: {v}' for k, v in non.items()) or '0'} | "
                     f"{fmt(c['server_cores'], 2)} / {fmt(c['k6_cores'], 2)} / {fmt(c['other_cores'], 2)} | {fmt(r['disk_probe_ms_p50'], 2)} |")
        L.append("")
    for r in res["open"]:
        L.append(f"### {r['scenario']} / {r['phase']}: {r['offered_per_s']} requests/s for {r['seconds']} s ({r['server_args']})")
        L.append("")
        L.append(f"- statuses: {r['statuses']}; accepted {r['accepted_per_s']}/s; completed (server) {r['completed_per_s']}/s; "
                 f"final {r['final']}; poll timeouts {r['lost_poll_timeout']}; poll errors {r['poll_errors']}; dropped iterations (whole run) {r['dropped_iterations']}")
        if r["retry_after_s"]:
            ra = r["retry_after_s"]
            L.append(f"- Retry-After on 429: {ra['count']} present and numeric (values {fmt(ra['p50'] if ra['count'] == 1 else min(ra['p50'], ra['max']), 0)}–{fmt(ra['max'], 0)} s, p50 {fmt(ra['p50'], 0)}), {r['retry_after_bad']} missing or not numeric; "
                     f"429 latency p50 {fmt(r['post429_ms']['p50'])} / p99 {fmt(r['post429_ms']['p99'])} ms")
        d, s = r["done_ms"] or {}, r["server_ms"] or {}
        L.append(f"- time to final state (client, polling): p50 {fmt(d.get('p50'), 0)} / p95 {fmt(d.get('p95'), 0)} / p99 {fmt(d.get('p99'), 0)} ms; "
                 f"server queued+running p50 {fmt(s.get('p50'), 0)} / p99 {fmt(s.get('p99'), 0)} ms")
        L.append(f"- max queue depth {r['max_queue_depth']}, max running {r['max_running']}, max RSS {r['max_rss_mib']} MiB, "
                 f"max fds {r['max_fds']}, max threads {r['max_threads']}, /healthz (new connection each 0.5 s) {r['healthz_ms']}, "
                 f"/healthz on the admin listener (--admin-addr, the probes' port) {r.get('admin_healthz_ms')}")
        L.append(f"- in the phase: server CPU {r['phase_server_cores']} cores, whole machine {r['phase_machine_cores']} cores; "
                 f"listen-queue overflows (machine) {r['listen_overflows']}")
        L.append("")
        L.append("| class | accepted | refused | done p50 | p95 | p99 | max (ms) | server p50 / p99 (ms) |")
        L.append("|---|---|---|---|---|---|---|---|")
        for cn, c in r["by_class"].items():
            d, s = c["done_ms"] or {}, c["server_ms"] or {}
            L.append(f"| {cn} | {c['accepted']} | {c['refused']} | {fmt(d.get('p50'), 0)} | {fmt(d.get('p95'), 0)} | "
                     f"{fmt(d.get('p99'), 0)} | {fmt(d.get('max'), 0)} | {fmt(s.get('p50'), 0)} / {fmt(s.get('p99'), 0)} |")
        L.append("")
    for n, sw in res["sweeps"].items():
        L.append(f"- sweep after {n}: {sw['accepted']} accepted ({sw['distinct_accepted']} distinct), "
                 f"sweep states {sw['sweep']}, k6 saw final {sw['k6_saw_final']}, **lost {sw['lost']}**, drained {sw['drained']} after {sw['drain_s']} s")
    L.append("")
    L.append("| server | args | store | peak RSS (VmHWM) MiB | end RSS MiB | max fds | max threads | /healthz max ms | /healthz failed | admin /healthz max ms | admin /healthz failed | exit on SIGTERM |")
    L.append("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for n, s in res["servers"].items():
        L.append(f"| {n} | `{s['args'].strip()}` | {s['fs']} | {s.get('peak_rss_mib')} | {s.get('end_rss_mib')} | {s.get('max_fds')} | "
                 f"{s.get('max_threads')} | {s.get('healthz_max_ms')} | {s.get('healthz_failed')} | "
                 f"{s.get('admin_healthz_max_ms')} | {s.get('admin_healthz_failed')} | {s.get('exit')} |")
    open(os.path.join(out, "results.md"), "w").write("\n".join(L) + "\n")


def plots(out, res, samples, steps):
    # 1. Closed loop: jobs/s and latency against users.
    if res["closed"]:
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
        series = {}
        for r in res["closed"]:
            if len(r["classes"]) > 1 or r["scenario"] == "workers":
                continue
            series.setdefault((r["classes"][0], r["store"]), []).append(r)
        colours = {"cube": "tab:blue", "spot": "tab:green"}
        for (mesh, store), rs in sorted(series.items()):
            x = [r["vus"] for r in rs]
            style = "-" if store != "tmpfs" else "--"
            col = colours.get(mesh, None)
            where = "tmpfs" if store == "tmpfs" else f"disk ({store})"
            a1.plot(x, [r["jobs_per_s"] for r in rs], style, color=col, marker="o", label=f"{mesh} 64³, {where}")
            a2.plot(x, [(r["latency_ms"] or {}).get("p99") for r in rs], style, color=col, marker="o", label=f"{mesh} p99, {where}")
            a2.plot(x, [(r["latency_ms"] or {}).get("p50") for r in rs], style, color=col, marker=".", alpha=0.4, label=f"{mesh} p50, {where}")
        ticks = sorted({r["vus"] for r in res["closed"]})
        for ax in (a1, a2):
            ax.set_xscale("log", base=2)
            ax.set_xticks(ticks)
            ax.set_xticklabels([str(t) for t in ticks])
        a2.set_yscale("log")
        a1.set_xlabel("concurrent clients (k6 VUs)")
        a2.set_xlabel("concurrent clients (k6 VUs)")
        a1.set_ylabel("jobs/s (201 Created, wait=30)")
        a2.set_ylabel("request latency (ms)")
        a1.set_title("Throughput, closed loop")
        a2.set_title("Latency of POST /v1/voxelize?wait=30")
        a1.legend(fontsize=8)
        a2.legend(fontsize=7, ncol=2)
        a1.grid(alpha=0.3)
        a2.grid(alpha=0.3, which="both")
        fig.tight_layout()
        fig.savefig(os.path.join(out, "load-closed.png"), dpi=110)
        plt.close(fig)
    # 2. Time series of the open-loop servers.
    for name in ("mix", "sat"):
        sm = samples.get(name)
        if not sm:
            continue
        t0 = sm[0]["t"]
        t = [r["t"] - t0 for r in sm]
        fig, axs = plt.subplots(4, 1, figsize=(10, 9), sharex=True)
        axs[0].plot(t, [r["depth"] for r in sm], label="voxd_queue_depth")
        axs[0].plot(t, [r["running"] for r in sm], label="voxd_queue_running")
        axs[0].set_ylabel("jobs")
        rate_t, rate = [], []
        for a, b in zip(sm, sm[1:]):
            if a["finished"] is not None and b["finished"] is not None and b["t"] > a["t"]:
                rate_t.append(b["t"] - t0)
                rate.append((b["finished"] - a["finished"]) / (b["t"] - a["t"]))
        axs[1].plot(rate_t, rate, color="tab:green")
        axs[1].set_ylabel("jobs finished/s")
        axs[2].plot(t, [r["rss_mib"] for r in sm], label="VmRSS")
        axs[2].plot(t, [r["hwm_mib"] for r in sm], "--", label="VmHWM")
        axs[2].set_ylabel("server MiB")
        axs[3].plot(t, [r["healthz_ms"] for r in sm], color="tab:red", label="service listener")
        if any(r["admin_healthz_ms"] is not None for r in sm):
            axs[3].plot(t, [r["admin_healthz_ms"] for r in sm], color="tab:blue", label="admin listener")
            axs[3].legend(loc="upper right", fontsize="small")
        axs[3].set_ylabel("/healthz ms")
        axs[3].set_xlabel("s since the server started")
        # shade the phases (from the console START and the phase lengths)
        for st in steps:
            if st["server"] == name and st["script"] == "closed.js":
                for ax in axs:
                    ax.axvspan(st["start"] - t0, st["end"] - t0, color="0.5", alpha=0.12)
                axs[0].text(st["start"] - t0 + 0.3, 0.80, "calibration:\n16 users, wait=30", transform=axs[0].get_xaxis_transform(), fontsize=8)
            if st["server"] != name or st["script"] != "open.js":
                continue
            phases = json.loads(st["args"].split("PHASES=", 1)[1].rsplit(" -e ", 1)[0])
            start = st["start"]
            for line in open(os.path.join(out, f"{st['scenario']}-{st['step']}.console.log"), errors="replace"):
                if 'msg="START ' in line:
                    start = int(line.split('msg="START ')[1].split('"')[0]) / 1000
            x = start - t0
            for i, p in enumerate(phases):
                for ax in axs:
                    ax.axvspan(x, x + p["duration"], color=f"C{i + 3}", alpha=0.12)
                axs[0].text(x + 0.3, 0.92, f"{p['name']}: {p['rate']}/s", transform=axs[0].get_xaxis_transform(), fontsize=8)
                x += p["duration"]
        for ax in axs:
            ax.grid(alpha=0.3)
        axs[0].legend(fontsize=8, loc="center left")
        axs[2].legend(fontsize=8, loc="center left")
        title = {"mix": "Mixed sizes, arrivals below then above capacity (queue capacity 64)",
                 "sat": "Past saturation (queue capacity 16)"}[name]
        axs[0].set_title(title)
        fig.tight_layout()
        fig.savefig(os.path.join(out, f"load-{name}.png"), dpi=110)
        plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
