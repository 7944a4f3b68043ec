// The runtime's policy folder (--policy-dir): load_policy names an artifact inside it, never a path outside
// it ("..", absolute paths and symlinks that leave it are refused), and with a key file only approved
// content loads: the SHA-256 of the whole file must have a verifying line in the approvals file
// (command_auth.hpp, messages/auth.py). The bytes hashed are the bytes parsed: no second read between them.
#pragma once
#include <memory>
#include <stdexcept>
#include <string>

#include "t1rt/artifact.hpp"
#include "t1rt/command_auth.hpp"

namespace t1rt {

// A name or path refused before any artifact parsing: outside the folder, or not approved.
class PolicyRefused : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class PolicyStore {
 public:
  PolicyStore() = default;
  // dir: the folder (must exist). approvers: the key file whose holders approve (null: content not checked,
  // the runtime has no key). approvals: the approvals file.
  PolicyStore(const std::string& dir, std::shared_ptr<const KeyRing> approvers, std::string approvals);
  const std::string& dir() const { return dir_; }
  const std::string& approvals() const { return approvals_; }
  bool checks_approval() const { return approvers_ != nullptr; }

  // load_policy's argument: a relative name inside the folder. Throws PolicyRefused or ArtifactError.
  PolicyArtifact load_name(const std::string& name) const;
  // A path (the startup --policy, SIGHUP's current file): it must lie inside the folder once resolved.
  PolicyArtifact load_path(const std::string& path) const;

 private:
  PolicyArtifact load_resolved(const std::string& real, const std::string& shown) const;
  std::string inside(const std::string& path, const std::string& shown) const;  // its real path, or throws
  std::string dir_;                                                             // real path, no trailing '/'
  std::shared_ptr<const KeyRing> approvers_;
  std::string approvals_;
};

}  // namespace t1rt
