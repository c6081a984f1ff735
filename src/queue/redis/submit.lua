-- Queues a job. ARGV: 2 id, 3 capacity (waiting jobs, all classes), 4 class, 5 cost, 6 method,
-- 7 record (JSON), 8 spec (JSON). Returns {'ok', position} | {'full', waiting} | {'exists', 0}.
local id, capacity, class = ARGV[2], tonumber(ARGV[3]), ARGV[4]
local waiting = redis.call('ZCARD', QUEUED)
if waiting >= capacity then return {'full', waiting} end
local key = job(id)
if redis.call('EXISTS', key) == 1 then return {'exists', 0} end
local s = stream(class)
ensure_group(s)
local now = now_ms()
local entry = redis.call('XADD', s, '*', 'id', id)
redis.call('HSET', key, 'state', 'queued', 'method', ARGV[6], 'record', ARGV[7], 'spec', ARGV[8],
  'class', class, 'stream', s, 'entry', entry, 'cost', ARGV[5], 'enq', ms(now),
  'attempts', '0', 'progress', '0')
redis.call('ZADD', QUEUED, now, id)
move(ARGV[6], nil, 'queued')
redis.call('PUBLISH', EVENTS, 'new')
return {'ok', redis.call('ZRANK', QUEUED, id) + 1}
