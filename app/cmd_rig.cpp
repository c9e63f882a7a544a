// augrig rig show RIG: what a rig file resolves to (render/rig_check.hpp): each camera's
// intrinsics, field of view, pose and optical axis in the tanker body frame, the baseline, the
// boom and where the receiver sits at contact, and warnings on what looks implausible.
#include "app/cli.hpp"
#include "render/rig_check.hpp"

namespace augrig::app {
namespace {

int rig_command(const std::vector<std::string>& args, std::ostream& out) {
  static const std::vector<OptionSpec> specs = {
      {"strict", ArgKind::kFlag, "", "exit 1 when there is a warning"},
  };
  std::vector<std::string> pos;
  const ParsedArgs a = parse_with_positionals(args, specs, {"show", "RIG"}, pos);
  if (a.help) {
    out << format_help("augrig rig show RIG.yaml|default [--strict]",
                       "Prints what a rig file resolves to: each camera's intrinsics, field of view, centre and\n"
                       "optical axis in the tanker body frame (FRD), the stereo baseline, the boom's limits and\n"
                       "where the receptacle lies in each image at contact (the boom at the middle of its limits);\n"
                       "then warnings on the implausible: a baseline of hundreds of metres (millimetres given as\n"
                       "metres), cameras sharing a centre or looking apart, the receiver behind a camera, out of\n"
                       "its image or inside the tanker. docs/RIG_FORMAT.md.",
                       specs);
    return kExitOk;
  }
  if (pos[0] != "show") usage_error("expected 'augrig rig show RIG', got 'augrig rig " + pos[0] + "'");
  const Rig rig = load_rig_arg(pos[1]);
  const RigModels models = unwrap(load_rig_models(rig));
  const BoomDimensions boom = models.boom_model ? models.boom_model->dims : BoomDimensions{};
  const RigSummary s = summarize_rig(rig, boom, models.receptacle_m);
  out << format_rig_summary(rig, s);
  return a.has("strict") && !s.warnings.empty() ? kExitRuntime : kExitOk;
}

}  // namespace

int cmd_rig(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  return guarded("rig", err, [&] { return rig_command(args, out); });
}

}  // namespace augrig::app
