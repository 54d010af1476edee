// The PostgreSQL backend of the world store (libpqxx): the same tables as SQLite, for a
// world that several processes or machines share. Each commit is durable when it returns
// (synchronous_commit, the server's default). A lost connection is reopened by the next
// call.
#pragma once

#include <memory>
#include <string>

#include "server/store/world_store.hpp"

namespace vox::store {

std::unique_ptr<WorldStore> open_postgres_store(const std::string& uri, const OpenOptions& options);
// The URI without its password, for messages.
std::string redact_uri(const std::string& uri);
// The first line of a (libpqxx) error message, for one-line errors.
inline std::string first_line(const std::string& s) { return s.substr(0, s.find('\n')); }

}  // namespace vox::store
