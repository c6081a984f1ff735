-- Queues a job. ARGV: 2 id, 3 capacity (waiting jobs, all classes), 4 class, 5 cost, 6 method,
-- 7 record (JSON), 8 spec (JSON), 9 owner (an API key's name, '' for none), 10 the owner's
-- limit of jobs queued or running (0: none). Returns {'ok', position} | {'full', waiting} |
-- {'owner', active} | {'exists', 0}.
local id, capacity, class = ARGV[2], tonumber(ARGV[3]), ARGV[4]
local owner, owner_max = ARGV[9], tonumber(ARGV[10])
local waiting = redis.call('ZCARD', QUEUED)
if waiting >= capacity then return {'full', waiting} end
local key = job(id)
if redis.call('EXISTS', key) == 1 then return {'exists', 0} end
-- The owner's jobs: a set of ids, pruned here of those that finished (or expired), so no other
-- script needs to know of it. At most the limit's worth of ids stay in it.
local owned = P .. ':owner:' .. owner
if owner ~= '' and owner_max > 0 then
  for _, other in ipairs(redis.call('SMEMBERS', owned)) do
    local st = redis.call('HGET', job(other), 'state')
    if st ~= 'queued' and st ~= 'running' then redis.call('SREM', owned, other) end
  end
  local active = redis.call('SCARD', owned)
  if active >= owner_max then return {'owner', active} end
end
local s = stream(class)
ensure_group(s)
local now = now_ms()
local entry = redis.call('XADD', s, '*', 'id', id)
redis.call('HSET', key, 'state', 'queued', 'method', ARGV[6], 'record', ARGV[7], 'spec', ARGV[8],
  'class', class, 'stream', s, 'entry', entry, 'cost', ARGV[5], 'enq', ms(now),
  'attempts', '0', 'progress', '0')
redis.call('ZADD', QUEUED, now, id)
if owner ~= '' and owner_max > 0 then redis.call('SADD', owned, id) end
move(ARGV[6], nil, 'queued')
redis.call('PUBLISH', EVENTS, 'new')
return {'ok', redis.call('ZRANK', QUEUED, id) + 1}
