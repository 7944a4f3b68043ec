// t1-runtime: the fixed-rate controller CLI. Exit codes:
//   0 ok (duration reached or SIGINT/SIGTERM)   2 usage error        3 bad policy artifact
//   4 LCM / DDS initialisation failure                5 --rt-required and a real-time setup step failed
//   6 key file refused (missing, malformed, or open to its group or others)
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "t1_contract.hpp"
#include "t1rt/controller.hpp"

namespace {
enum ExitCode { kExitOk = 0, kExitUsage = 2, kExitBadArtifact = 3, kExitLcm = 4, kExitRt = 5, kExitKey = 6 };

constexpr double kMaxPrepareS = 10.0;  // a longer ramp is a typo, not a choice
// --duration above this (30 days) is a typo or an overflow in waiting: run without --duration instead.
constexpr double kMaxDurationS = 30.0 * 24 * 3600;
constexpr long kMaxRtCpu = 1023;  // CPU_SETSIZE - 1: the highest core sched_setaffinity can name

// Whole-string decimal integer in [lo, hi]; false on anything else ("abc", "1x", "", overflow).
bool parse_long(const char* text, long lo, long hi, long* out) {
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(text, &end, 10);
  if (end == text || *end || errno == ERANGE || v < lo || v > hi) return false;
  *out = v;
  return true;
}
t1rt::Controller* g_controller = nullptr;

void on_stop_signal(int) {
  if (g_controller) g_controller->stop();
}
void on_sighup(int) { t1rt::Controller::notify_sighup(); }

// f: opened when the arguments were read, so a path that cannot be written is refused before the run.
bool write_histogram(FILE* f, t1rt::PeriodicTask& task) {
  const std::string bins = task.histogram().json();
  std::fprintf(f, "{\"lateness_us\": %s, \"max_us\": %.1f, \"overruns\": %lld, \"ticks\": %lld}\n", bins.c_str(),
               task.lateness().max(), static_cast<long long>(task.overruns()),
               static_cast<long long>(task.lateness().count()));
  return std::fclose(f) == 0;
}

void usage(FILE* out) {
  std::fprintf(
      out,
      "usage: t1-runtime --policy PATH [--policy-upright PATH] [options]\n"
      "  --policy PATH          policy artifact (*.safetensors, policies/ARTIFACT.md); required. A keyframe chain's\n"
      "                         folder (chain.json: roll, rise, stand; policies/getup_keyframe): chain mode (sim "
      "only),\n"
      "                         switched by the Trunk's height from T1_SIM_STATUS (run the sim with --status-rate\n"
      "                         500); one gain set; no hot reload\n"
      "  --policy-upright PATH  composite mode (sim only): --policy is the getup member, run while the waist is\n"
      "                         below 0.5 m, PATH the upright/joystick member; waist height comes from\n"
      "                         T1_SIM_STATUS (privileged simulator signal; run the sim with --status-rate 500);\n"
      "                         both artifacts must share one gain set; no hot reload\n"
      "  --clock realtime|lockstep  realtime: own 500 Hz clock (default); lockstep: one tick per T1_JOINT_STATE,\n"
      "                         answered by T1_JOINT_CMD with state_seq = that state's seq\n"
      "  --transport lcm|dds    the robot link (default lcm). dds: the real T1's own topics over Cyclone DDS,\n"
      "                         state from rt/low_state, LowCmd (SERIAL) to rt/joint_ctrl, domain from the contract;\n"
      "                         lockstep: one tick per LowState sample. Joystick, runtime commands and status stay "
      "LCM\n"
      "  --lcm-url URL          LCM URL (default: $T1_LCM_URL, else the contract default)\n"
      "  --rt                   SCHED_FIFO, mlockall, CPU pinning, /dev/cpu_dma_latency=0 (failures reported)\n"
      "  --rt-required          like --rt, but any failed step is fatal (exit 5)\n"
      "  --rt-cpu N             core for --rt pinning (default 1; -1 = no pinning)\n"
      "  --key FILE             take the commands and joystick signed by a sender of FILE (messages/auth.py;\n"
      "                         mode 600, else refused); --policy and load_policy need approved content\n"
      "  --unauthenticated      a bench setup: take every command and joystick unsigned (said at start and in\n"
      "                         the status info). Without --key or this flag only estop is taken, no joystick\n"
      "  --policy-dir DIR       the folder load_policy names an artifact in (default: the folder of --policy);\n"
      "                         with --key the startup --policy must lie in it too\n"
      "  --approvals FILE       with --key: the approvals file (default: DIR/approvals)\n"
      "  --robot-key FILE       take the robot's state (T1_IMU, T1_JOINT_STATE) only when signed by a sender of\n"
      "                         FILE (messages/auth.py, mode 0600; the robot's own key, not the operator's):\n"
      "                         unsigned, wrong-key, stale and replayed frames are refused and counted. Without\n"
      "                         it state is unauthenticated (a bench): a second sequence stream is a FAULT\n"
      "  --autostart            go PASSIVE -> DAMPING -> PREPARE -> POLICY by itself\n"
      "  --prepare-s S          PREPARE ramp duration in seconds (default 2; 0 < S <= 10)\n"
      "  --duration S           stop after S wall-clock seconds, 0 < S <= 30 days (default: until SIGINT/SIGTERM)\n"
      "  --quiet                no live status line\n"
      "  --lateness-histogram PATH  realtime: at exit, write every tick's wake-up lateness as a 1 us histogram\n"
      "                         (JSON: bin_us, count, max_us, overruns, ticks) to PATH (make bench-soak)\n"
      "  --help                 this text\n"
      "signals: SIGHUP reloads the current policy file; SIGINT/SIGTERM stop.\n"
      "exit codes: 0 ok, 2 usage, 3 bad or refused artifact, 4 LCM/DDS init failure, 5 --rt-required setup\n"
      "failure, 6 key file refused\n");
}

// The first line: who may command this runtime.
void print_authority(const t1rt::ControllerOptions& opt, const t1rt::PolicyStore& store) {
  if (opt.auth == t1rt::AuthMode::kSigned) {
    std::string ids;
    for (std::size_t i = 0; i < opt.keys->size(); ++i) ids += (i ? ", " : "") + std::to_string(opt.keys->sender_id(i));
    std::fprintf(stderr, "t1-runtime: commands signed: key file %s (senders %s); artifacts in %s approved in %s\n",
                 opt.keys->path().c_str(), ids.c_str(), store.dir().c_str(), store.approvals().c_str());
  } else if (opt.auth == t1rt::AuthMode::kUnauthenticated) {
    std::fprintf(stderr,
                 "t1-runtime: commands unauthenticated (--unauthenticated, a bench setup): any program on "
                 "the LCM group may command this robot; load_policy loads any artifact in %s\n",
                 store.dir().c_str());
  } else {
    std::fprintf(stderr,
                 "t1-runtime: commands: estop only (no --key): every other runtime_cmd_t and the joystick "
                 "are refused; --key FILE takes the operator's signed ones\n");
  }
}
}  // namespace

int main(int argc, char** argv) {
  t1rt::ControllerOptions opt;
  std::string cli_url;
  bool rt = false, rt_required = false;
  t1rt::RtOptions rt_options;
  std::string histogram_path, key_path, robot_key_path;
  FILE* histogram_file = nullptr;
  bool unauthenticated = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* name) -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "t1-runtime: %s needs a value\n", name);
        std::exit(kExitUsage);
      }
      return argv[++i];
    };
    if (a == "--help" || a == "-h") {
      usage(stdout);
      return kExitOk;
    } else if (a == "--policy") opt.policy_path = value("--policy");
    else if (a == "--policy-upright") opt.upright_policy_path = value("--policy-upright");
    else if (a == "--clock") {
      const std::string c = value("--clock");
      if (c == "realtime") opt.clock = t1rt::ClockMode::kRealtime;
      else if (c == "lockstep") opt.clock = t1rt::ClockMode::kLockstep;
      else {
        std::fprintf(stderr, "t1-runtime: --clock must be realtime or lockstep, not '%s'\n", c.c_str());
        return kExitUsage;
      }
    } else if (a == "--transport") {
      const std::string t = value("--transport");
      if (t == "lcm") opt.robot_link = t1rt::RobotLinkKind::kLcm;
      else if (t == "dds") opt.robot_link = t1rt::RobotLinkKind::kDds;
      else {
        std::fprintf(stderr, "t1-runtime: --transport must be lcm or dds, not '%s'\n", t.c_str());
        return kExitUsage;
      }
    } else if (a == "--lcm-url") cli_url = value("--lcm-url");
    else if (a == "--rt") rt = true;
    else if (a == "--rt-required") rt = rt_required = true;
    else if (a == "--rt-cpu") {
      const char* v = value("--rt-cpu");
      long cpu = 0;
      if (!parse_long(v, -1, kMaxRtCpu, &cpu)) {
        std::fprintf(stderr, "t1-runtime: --rt-cpu needs a core number in [-1, %ld] (-1 = no pinning), not '%s'\n",
                     kMaxRtCpu, v);
        return kExitUsage;
      }
      rt_options.cpu = static_cast<int>(cpu);
    } else if (a == "--key") key_path = value("--key");
    else if (a == "--robot-key") robot_key_path = value("--robot-key");
    else if (a == "--unauthenticated") unauthenticated = true;
    else if (a == "--policy-dir") opt.policy_dir = value("--policy-dir");
    else if (a == "--approvals") opt.approvals_path = value("--approvals");
    else if (a == "--autostart") opt.autostart = true;
    else if (a == "--prepare-s") {
      // Evaluations that spawn the robot standing in its default pose need no 2 s ramp: a static PD stand
      // is not a balance controller and can tip over before the policy starts.
      char* end = nullptr;
      const char* v = value("--prepare-s");
      opt.safety.prepare_duration_s = std::strtod(v, &end);
      if (!end || *end || !(opt.safety.prepare_duration_s > 0 && opt.safety.prepare_duration_s <= kMaxPrepareS)) {
        std::fprintf(stderr, "t1-runtime: --prepare-s needs seconds in (0, %g], not '%s'\n", kMaxPrepareS, v);
        return kExitUsage;
      }
    } else if (a == "--quiet") opt.quiet = true;
    else if (a == "--lateness-histogram") {
      histogram_path = value("--lateness-histogram");
      histogram_file = std::fopen(histogram_path.c_str(), "w");
      if (!histogram_file) {
        std::fprintf(stderr, "t1-runtime: --lateness-histogram: cannot write %s: %s\n", histogram_path.c_str(),
                     std::strerror(errno));
        return kExitUsage;
      }
    } else if (a == "--duration") {
      char* end = nullptr;
      const char* v = value("--duration");
      opt.duration_s = std::strtod(v, &end);
      // NaN compares false with everything: the test is written so that NaN (and inf) fail it.
      if (end == v || *end || !(opt.duration_s > 0 && opt.duration_s <= kMaxDurationS)) {
        std::fprintf(stderr, "t1-runtime: --duration needs finite seconds in (0, %g], not '%s'\n", kMaxDurationS, v);
        return kExitUsage;
      }
    } else {
      std::fprintf(stderr, "t1-runtime: unknown argument '%s'\n", a.c_str());
      usage(stderr);
      return kExitUsage;
    }
  }
  if (opt.policy_path.empty()) {
    std::fprintf(stderr, "t1-runtime: --policy PATH is required\n");
    usage(stderr);
    return kExitUsage;
  }
  if (unauthenticated && !key_path.empty()) {
    std::fprintf(stderr, "t1-runtime: --key and --unauthenticated exclude each other\n");
    return kExitUsage;
  }
  if (!opt.approvals_path.empty() && key_path.empty()) {
    std::fprintf(stderr, "t1-runtime: --approvals needs --key (approvals are checked with its keys)\n");
    return kExitUsage;
  }
  opt.lcm_url = t1rt::resolve_lcm_url(cli_url);
  opt.dds_domain_id = t1::kDdsDomainId;
  opt.auth = unauthenticated    ? t1rt::AuthMode::kUnauthenticated
             : key_path.empty() ? t1rt::AuthMode::kEstopOnly
                                : t1rt::AuthMode::kSigned;
  if (!key_path.empty()) {
    std::string error;
    opt.keys = t1rt::KeyRing::load(key_path, &error);
    if (!opt.keys) {
      std::fprintf(stderr, "t1-runtime: refused: %s\n", error.c_str());
      return kExitKey;
    }
  }

  if (!robot_key_path.empty()) {
    std::string error;
    opt.robot_keys = t1rt::KeyRing::load(robot_key_path, &error);
    if (!opt.robot_keys) {
      std::fprintf(stderr, "t1-runtime: refused: robot %s\n", error.c_str());
      return kExitKey;
    }
  }

  std::unique_ptr<t1rt::PolicyEngine> engine, upright;
  std::array<std::unique_ptr<t1rt::PolicyEngine>, t1rt::kChainStages> chain;
  t1rt::ChainFile chain_file;
  const bool chain_mode = t1rt::is_chain_folder(opt.policy_path);
  if (chain_mode && !opt.upright_policy_path.empty()) {
    std::fprintf(stderr, "t1-runtime: --policy-upright pairs a getup artifact, not a keyframe chain's folder (%s)\n",
                 opt.policy_path.c_str());
    return kExitUsage;
  }
  std::string loading = opt.policy_path;
  try {
    const t1rt::PolicyStore store = t1rt::make_policy_store(opt);
    // With a key the startup policies follow load_policy's rule: inside the folder, approved content.
    auto load = [&](const std::string& path) {
      return std::make_unique<t1rt::PolicyEngine>(store.checks_approval() ? store.load_path(path)
                                                                          : t1rt::load_artifact(path));
    };
    if (chain_mode) {
      chain_file = t1rt::read_chain_file(opt.policy_path);
      for (std::size_t i = 0; i < t1rt::kChainStages; ++i) {
        loading = chain_file.members[i];
        chain[i] = load(chain_file.members[i]);
        if (i > 0) t1rt::check_composite_pair(chain[0]->artifact(), chain[i]->artifact());
      }
    } else {
      engine = load(opt.policy_path);
    }
    if (!opt.upright_policy_path.empty()) {
      loading = opt.upright_policy_path;
      upright = load(opt.upright_policy_path);
      loading = opt.policy_path + " + " + opt.upright_policy_path;
      t1rt::check_composite_pair(engine->artifact(), upright->artifact());
    }
    print_authority(opt, store);  // after the policies: a refused one is the only line
  } catch (const t1rt::PolicyRefused& e) {
    std::fprintf(stderr, "t1-runtime: refused: %s\n", e.what());
    return kExitBadArtifact;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "t1-runtime: bad policy artifact %s: %s\n", loading.c_str(), e.what());
    return kExitBadArtifact;
  }
  std::vector<std::pair<std::string, const t1rt::PolicyEngine*>> members;
  if (chain_mode)
    for (std::size_t i = 0; i < t1rt::kChainStages; ++i)
      members.emplace_back(std::string(t1rt::stage_name(static_cast<t1rt::ChainStage>(i))) + " member: ",
                           chain[i].get());
  else if (upright) members = {{"getup member: ", engine.get()}, {"upright member: ", upright.get()}};
  else members = {{"", engine.get()}};
  for (const auto& [label, p] : members) {
    const auto& art = p->artifact();
    std::fprintf(stderr,
                 "t1-runtime: %spolicy '%s' hash %.12s trained=%s obs %d layers %zu (MLP kernel %s); clock %s; "
                 "LCM %s; robot link %s\n",
                 label.c_str(), art.name.c_str(), art.content_hash.c_str(), art.trained ? "true" : "false",
                 art.obs_size, art.layers.size(), p->mlp_variant(), t1rt::clock_name(opt.clock), opt.lcm_url.c_str(),
                 t1rt::robot_link_description(opt.robot_link));
  }
  if (opt.robot_keys)
    std::fprintf(stderr, "t1-runtime: state: only the robot's signed frames (--robot-key %s, %zu senders)\n",
                 robot_key_path.c_str(), opt.robot_keys->size());
  else if (t1rt::state_on_lcm(opt.robot_link))
    std::fprintf(stderr,
                 "t1-runtime: state unauthenticated (no --robot-key, a bench setup): any program on the LCM "
                 "group can publish T1_IMU / T1_JOINT_STATE; a second sequence stream is a FAULT (rule R12)\n");
  if (upright)
    std::fprintf(stderr,
                 "t1-runtime: COMPOSITE mode: getup below waist %.2f m, else upright; waist height from "
                 "T1_SIM_STATUS (privileged simulator signal, not available on a robot)\n",
                 t1rt::kGetupSwitchWaistHeightM);
  if (chain_mode)
    std::fprintf(stderr,
                 "t1-runtime: CHAIN mode: roll -> rise -> stand, the rise hands over at %s (|u - e_z| < %.2f); "
                 "Trunk height from T1_SIM_STATUS (privileged simulator signal, not available on a robot)\n",
                 chain_file.handover.c_str(), chain_file.handover_up_error);

  t1rt::Controller controller = chain_mode ? t1rt::Controller(opt, std::move(chain), chain_file.handover_up_error)
                                           : t1rt::Controller(opt, std::move(engine), std::move(upright));
  std::string error;
  if (!controller.open(&error)) {
    std::fprintf(stderr, "t1-runtime: transport init failed: %s\n", error.c_str());
    return kExitLcm;
  }

  t1rt::RtSetup rt_setup;
  if (rt) {
    for (const std::string& line : rt_setup.apply(rt_options))
      std::fprintf(stderr, "t1-runtime: rt %s\n", line.c_str());
    if (rt_required && !rt_setup.all_ok()) {
      std::fprintf(stderr, "t1-runtime: --rt-required: real-time setup failed\n");
      return kExitRt;
    }
  }
  g_controller = &controller;
  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);
  std::signal(SIGHUP, on_sighup);
  controller.run();
  g_controller = nullptr;
  auto& task = controller.task();
  if (histogram_file && !write_histogram(histogram_file, task)) {
    std::fprintf(stderr, "t1-runtime: --lateness-histogram: cannot write %s: %s\n", histogram_path.c_str(),
                 std::strerror(errno));
    return kExitUsage;
  }
  std::fprintf(stderr,
               "t1-runtime: stopped in %s after %lld ticks (%lld policy); lateness p99 %.1f us max %.1f us; "
               "compute p99 %.1f us max %.1f us; overruns %lld; last fault: %s\n",
               t1rt::mode_name(controller.supervisor().mode()), static_cast<long long>(controller.ticks()),
               static_cast<long long>(controller.policy_ticks()), task.lateness().p99(), task.lateness().max(),
               task.compute().p99(), task.compute().max(), static_cast<long long>(task.overruns()),
               controller.supervisor().last_fault()[0] ? controller.supervisor().last_fault() : "none");
  return kExitOk;
}
