-- The shared queue's numbers: {waiting, running, ms the oldest waiting job has waited (-1:
-- none), {waiting per class}, {'state|method', jobs, ...}}.
local now = now_ms()
local oldest = redis.call('ZRANGE', QUEUED, 0, 0, 'WITHSCORES')
local age = -1
if oldest[2] then age = now - tonumber(oldest[2]) end
local classes = {}
for _, class in ipairs(CLASSES) do
  local s = stream(class)
  local n = 0
  if redis.call('EXISTS', s) == 1 then
    -- Entries are deleted once done with, so the stream's length less the delivered ones is
    -- what waits.
    local pending = redis.pcall('XPENDING', s, GROUP)
    local delivered = 0
    if type(pending) == 'table' then delivered = tonumber(pending[1]) or 0 end
    n = math.max(0, redis.call('XLEN', s) - delivered)
  end
  table.insert(classes, n)
end
return {redis.call('ZCARD', QUEUED), redis.call('ZCARD', RUNNING), age, classes,
  redis.call('HGETALL', COUNTS)}
