// The policy folder's rules (policy_store.hpp).
#include "t1rt/policy_store.hpp"

#include <openssl/sha.h>

#include <cerrno>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace t1rt {

namespace {
std::string real_path(const std::string& path, int* err) {
  char buf[PATH_MAX];
  if (!::realpath(path.c_str(), buf)) {
    *err = errno;
    return {};
  }
  *err = 0;
  return buf;
}
}  // namespace

PolicyStore::PolicyStore(const std::string& dir, std::shared_ptr<const KeyRing> approvers, std::string approvals)
    : approvers_(std::move(approvers)), approvals_(std::move(approvals)) {
  int err = 0;
  dir_ = real_path(dir, &err);
  if (dir_.empty()) throw PolicyRefused("policy folder " + dir + ": " + std::strerror(err));
}

std::string PolicyStore::inside(const std::string& path, const std::string& shown) const {
  int err = 0;
  const std::string real = real_path(path, &err);
  if (real.empty()) throw PolicyRefused("policy '" + shown + "': " + std::strerror(err) + " (in " + dir_ + ")");
  if (real.compare(0, dir_.size() + 1, dir_ + "/") != 0)
    throw PolicyRefused("policy '" + shown + "' resolves to " + real + ", outside the policy folder " + dir_ +
                        " (a symlink leaving it?)");
  return real;
}

PolicyArtifact PolicyStore::load_name(const std::string& name) const {
  if (name.empty()) throw PolicyRefused("load_policy needs an artifact name inside the policy folder " + dir_);
  if (name[0] == '/')
    throw PolicyRefused("policy '" + name + "': an absolute path; load_policy takes a name inside the policy folder " +
                        dir_);
  std::istringstream parts(name);
  for (std::string part; std::getline(parts, part, '/');)
    if (part == "..") throw PolicyRefused("policy '" + name + "': '..' leaves the policy folder " + dir_);
  return load_resolved(inside(dir_ + "/" + name, name), name);
}

PolicyArtifact PolicyStore::load_path(const std::string& path) const { return load_resolved(inside(path, path), path); }

PolicyArtifact PolicyStore::load_resolved(const std::string& real, const std::string& shown) const {
  std::error_code ec;
  if (std::filesystem::is_directory(real, ec))
    throw PolicyRefused("policy '" + shown + "': a folder, not an artifact file (*.safetensors)");
  std::ifstream in(real, std::ios::binary);
  if (!in) throw PolicyRefused("policy '" + shown + "': cannot open " + real);
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string bytes = ss.str();
  if (approvers_) {
    uint8_t digest[kSha256Bytes];
    SHA256(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size(), digest);
    std::string why;
    if (!approvers_->approves(approvals_, digest, &why))
      throw PolicyRefused("policy '" + shown + "' not loaded: " + why);
  }
  return parse_artifact(real, bytes);
}

}  // namespace t1rt
