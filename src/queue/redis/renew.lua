-- A running job's worker renews its lease (resets its entry's idle time) and reports its
-- progress. ARGV: 2 id, 3 token, 4 consumer, 5 progress. Returns 'ok', 'canceled' (stop), or
-- 'lost' (another worker took the job over, or it is gone: stop, the result is not this one's).
local key = job(ARGV[2])
local state = redis.call('HGET', key, 'state')
if not state or redis.call('HGET', key, 'owner') ~= ARGV[3] then return 'lost' end
if state == 'canceled' then return 'canceled' end
if state ~= 'running' then return 'lost' end
redis.call('XCLAIM', redis.call('HGET', key, 'stream'), GROUP, ARGV[4], 0,
  redis.call('HGET', key, 'entry'), 'JUSTID')
redis.call('HSET', key, 'progress', ARGV[5])
return 'ok'
