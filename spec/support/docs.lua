-- Reading the docs' Markdown in the specs that run its examples: its fenced blocks and its
-- sections.

local D = {}

--- The fenced blocks of a Markdown text: {lang =, text =, line =}, in order.
function D.fenced(text)
  local out, lang, body, start = {}, nil, nil, nil
  local n = 0
  for line in (text .. "\n"):gmatch("([^\n]*)\n") do
    n = n + 1
    if lang == nil then
      local l = line:match("^```(%w*)%s*$")
      if l then lang, body, start = l, {}, n + 1 end
    elseif line:match("^```%s*$") then
      out[#out + 1] = { lang = lang, text = table.concat(body, "\n") .. "\n", line = start }
      lang = nil
    else
      body[#body + 1] = line
    end
  end
  return out
end

--- The part of a text from a heading (plain text) to the next `stop` after it (plain text;
-- default the next level-2 heading, "\n## "), or to the end.
function D.section(text, heading, stop)
  stop = stop or "\n## "
  local a = assert(text:find(heading, 1, true), heading)
  local b = text:find(stop, a + #heading, true) or #text
  return text:sub(a, b)
end

return D
