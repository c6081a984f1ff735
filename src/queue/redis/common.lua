-- Prepended to every script of the voxd queue (src/queue/redis/*.lua). ARGV[1] is the key
-- prefix; the other arguments are each script's own. A script runs atomically, so every state
-- change of a job is one step, whichever replica makes it. Times are the Redis server's clock
-- (TIME), the one clock every replica shares.
local P = ARGV[1]
local GROUP = 'workers'
local QUEUED = P .. ':queued'   -- sorted set: waiting job id -> enqueued (ms)
local RUNNING = P .. ':running' -- sorted set: running job id -> started (ms)
local COUNTS = P .. ':counts'   -- hash: 'state|method' -> jobs
local EVENTS = P .. ':events'   -- channel: 'new', 'done <id>'
local CLASSES = {'small', 'medium', 'large'}

local function stream(class) return P .. ':stream:' .. class end
local function job(id) return P .. ':job:' .. id end

local function now_ms()
  local t = redis.call('TIME')
  return tonumber(t[1]) * 1000 + math.floor(tonumber(t[2]) / 1000)
end

local function ms(n) return string.format('%.0f', n) end

-- One job of `method` moves from state `from` to state `to` (either may be nil).
local function move(method, from, to)
  if from then redis.call('HINCRBY', COUNTS, from .. '|' .. method, -1) end
  if to then redis.call('HINCRBY', COUNTS, to .. '|' .. method, 1) end
end

-- The consumer group exists (also after a Redis that lost its data came back empty).
local function ensure_group(s)
  redis.pcall('XGROUP', 'CREATE', s, GROUP, '0', 'MKSTREAM')
end

-- The entry is done with: acknowledged and removed, so the stream holds only live jobs.
local function drop_entry(s, entry)
  redis.call('XACK', s, GROUP, entry)
  redis.call('XDEL', s, entry)
end

-- Job `id` reached a final state: its record expires after `ttl` s, its waiters hear of it.
local function finished(id, ttl)
  redis.call('EXPIRE', job(id), ttl)
  redis.call('ZREM', RUNNING, id)
  redis.call('PUBLISH', EVENTS, 'done ' .. id)
end
