// The SQLite backend of the world store: one file, `world.sqlite`, in the world directory;
// WAL mode with synchronous=FULL, so a committed append survives kill -9 and power loss.
#pragma once

#include <filesystem>
#include <memory>

#include "server/store/world_store.hpp"

namespace vox::store {

inline constexpr const char* kSqliteFileName = "world.sqlite";

std::unique_ptr<WorldStore> open_sqlite_store(const std::filesystem::path& dir,
                                              const OpenOptions& options);

}  // namespace vox::store
