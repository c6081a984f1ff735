-- Cancels a job. ARGV: 2 id, 3 record TTL (s). A queued job's entry is deleted (it is never
-- delivered); a running one is marked canceled, which its worker hears at its next renewal
-- (and stops), its entry cleared by that worker or by whoever reclaims it. Returns
-- {'canceled', previous state} | {'final', state} | {'none', ''}.
local id = ARGV[2]
local key = job(id)
local state = redis.call('HGET', key, 'state')
if not state then return {'none', ''} end
if state ~= 'queued' and state ~= 'running' then return {'final', state} end
if state == 'queued' then
  redis.call('XDEL', redis.call('HGET', key, 'stream'), redis.call('HGET', key, 'entry'))
  redis.call('ZREM', QUEUED, id)
end
redis.call('HSET', key, 'state', 'canceled', 'end', ms(now_ms()))
move(redis.call('HGET', key, 'method'), state, 'canceled')
finished(id, tonumber(ARGV[3]))
return {'canceled', state}
