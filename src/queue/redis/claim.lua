-- Takes the next job for consumer ARGV[2]. ARGV: 3 lease (ms), 4 max attempts, 5 age credit
-- (cost units per second waited), 6 record TTL (s), 7 lease (s, for the message).
--
-- First a job whose worker stopped renewing its lease (idle in the group's pending list for a
-- lease: XAUTOCLAIM), then a new one: of the three classes' next undelivered entries, the one
-- with the lowest cost - credit x seconds waited (the in-process queue's rule, applied to the
-- heads of the classes, each class in arrival order).
--
-- Returns nil (nothing to do), or
--   {'run', id, token, stream, entry, spec, record, attempt}: run it; `token` names this run,
--   {'failed', id}: its last attempt's worker died too; it is failed now,
--   {'cleaned', id, state, volume}: a finished or canceled job's entry, cleared,
--   {'dropped', id}: an entry without a record, cleared.
-- The caller asks again after anything but nil or 'run'.
local consumer, lease = ARGV[2], tonumber(ARGV[3])
local max_attempts, credit, ttl = tonumber(ARGV[4]), tonumber(ARGV[5]), tonumber(ARGV[6])

local function start(s, entry, id)
  local key = job(id)
  local state = redis.call('HGET', key, 'state')
  if not state then
    drop_entry(s, entry)
    return {'dropped', id}
  end
  if state ~= 'queued' and state ~= 'running' then
    drop_entry(s, entry)
    redis.call('ZREM', RUNNING, id)
    return {'cleaned', id, state, redis.call('HGET', key, 'volume') or ''}
  end
  local method = redis.call('HGET', key, 'method')
  local attempts = tonumber(redis.call('HGET', key, 'attempts') or '0')
  local now = now_ms()
  if state == 'running' and attempts >= max_attempts then
    local detail = string.format(
      'the job was started %d times (--max-attempts) and each time the replica running it ' ..
      'stopped renewing its lease for %s s (--lease-seconds): it died, was killed or lost ' ..
      'its connection to Redis (the last was %s); a job that brings replicas down may need ' ..
      'a coarser grid or a cheaper fill',
      attempts, ARGV[7], redis.call('HGET', key, 'owner') or '?')
    redis.call('HSET', key, 'state', 'failed', 'end', ms(now),
      'error', cjson.encode({kind = 'engine-failure', detail = detail}))
    drop_entry(s, entry)
    move(method, 'running', 'failed')
    finished(id, ttl)
    return {'failed', id}
  end
  attempts = attempts + 1
  local token = consumer .. '#' .. attempts
  if state == 'queued' then
    redis.call('ZREM', QUEUED, id)
    move(method, 'queued', 'running')
  end
  redis.call('HSET', key, 'state', 'running', 'owner', token, 'attempts', tostring(attempts),
    'start', ms(now), 'progress', '0')
  redis.call('ZADD', RUNNING, now, id)
  return {'run', id, token, s, entry, redis.call('HGET', key, 'spec'),
    redis.call('HGET', key, 'record'), tostring(attempts)}
end

-- 1. A job whose lease ran out.
for _, class in ipairs(CLASSES) do
  local s = stream(class)
  ensure_group(s)
  local cursor = '0-0'
  for _ = 1, 100 do
    local r = redis.call('XAUTOCLAIM', s, GROUP, consumer, lease, cursor, 'COUNT', 1)
    cursor = r[1]
    local e = r[2][1]
    if e then
      if e[2] then return start(s, e[1], e[2][2]) end
      drop_entry(s, e[1]) -- deleted meanwhile (Redis 6.2 lists such entries as nil)
      return {'dropped', ''}
    end
    if cursor == '0-0' then break end
  end
end

-- 2. The best new job among the classes' heads.
local now = now_ms()
local best, best_score = nil, nil
for _, class in ipairs(CLASSES) do
  local s = stream(class)
  local last = '0-0'
  for _, g in ipairs(redis.call('XINFO', 'GROUPS', s)) do
    local name, delivered = nil, nil
    for k = 1, #g, 2 do
      if g[k] == 'name' then name = g[k + 1] elseif g[k] == 'last-delivered-id' then delivered = g[k + 1] end
    end
    if name == GROUP then last = delivered end
  end
  local head = redis.call('XRANGE', s, '(' .. last, '+', 'COUNT', 1)[1]
  if head then
    local waited = (now - tonumber(string.match(head[1], '^(%d+)'))) / 1000
    local cost = tonumber(redis.call('HGET', job(head[2][2]), 'cost') or '0')
    local score = cost - credit * waited
    if best_score == nil or score < best_score then best, best_score = s, score end
  end
end
if not best then return nil end
local got = redis.call('XREADGROUP', 'GROUP', GROUP, consumer, 'COUNT', 1, 'STREAMS', best, '>')
local e = got and got[1] and got[1][2][1]
if not e then return nil end
return start(best, e[1], e[2][2])
