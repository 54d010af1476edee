// Finding the C++ programs the tests run: the environment (set by CTest) or the build
// folder of this checkout.
import { existsSync } from "node:fs";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";

const repo = join(dirname(fileURLToPath(import.meta.url)), "..", "..", "..");

/** @param {string} env @param {string} name @returns {string|null} */
export function findTool(env, name) {
  if (process.env[env]) return process.env[env];
  const built = join(repo, "build", "bin", name);
  return existsSync(built) ? built : null;
}
