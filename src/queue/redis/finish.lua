-- Records the end of a run, if the job is still this run's (a compare-and-set on the token).
-- ARGV: 2 id, 3 token, 4 state (succeeded | failed), 5 volume id or '', 6 error (JSON) or '',
-- 7 progress, 8 record TTL (s). Returns {'done', state, volume} when recorded, else
-- {'other', state, volume} (what the job is now: canceled meanwhile, or another worker's) or
-- {'gone', '', ''}.
local id, token = ARGV[2], ARGV[3]
local key = job(id)
local state = redis.call('HGET', key, 'state')
if not state then return {'gone', '', ''} end
local owner = redis.call('HGET', key, 'owner')
local s, entry = redis.call('HGET', key, 'stream'), redis.call('HGET', key, 'entry')
if state == 'running' and owner == token then
  redis.call('HSET', key, 'state', ARGV[4], 'end', ms(now_ms()), 'progress', ARGV[7])
  if ARGV[5] ~= '' then redis.call('HSET', key, 'volume', ARGV[5]) end
  if ARGV[6] ~= '' then redis.call('HSET', key, 'error', ARGV[6]) end
  drop_entry(s, entry)
  move(redis.call('HGET', key, 'method'), 'running', ARGV[4])
  finished(id, tonumber(ARGV[8]))
  return {'done', ARGV[4], ARGV[5]}
end
-- Canceled while this run went on: its entry is this run's to clear.
if owner == token and state ~= 'queued' and state ~= 'running' then drop_entry(s, entry) end
return {'other', state, redis.call('HGET', key, 'volume') or ''}
