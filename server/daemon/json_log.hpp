// voxeld's logs as JSON for log shippers (--log-format json): one object per line,
// {"time":"2026-12-07T15:09:21.123456+00:00","level":"info","thread":1234,"msg":"..."},
// the same events as the text format. Any thread; use_json_logs() before logging starts.
#pragma once

#include <string>
#include <string_view>

namespace vox::daemon {

// `text` as the inside of a JSON string: quotes, backslashes and control characters
// escaped; valid UTF-8 kept; each byte of an invalid sequence becomes U+FFFD.
void append_json_escaped(std::string_view text, std::string& out);

// Every logger's lines from now on are JSON objects.
void use_json_logs();

}  // namespace vox::daemon
