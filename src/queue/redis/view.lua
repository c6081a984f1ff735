-- A job's fields, the server's time (ms) and its 0-based place among waiting jobs (-1: not
-- waiting). ARGV: 2 id.
local fields = redis.call('HGETALL', job(ARGV[2]))
return {fields, now_ms(), redis.call('ZRANK', QUEUED, ARGV[2]) or -1}
