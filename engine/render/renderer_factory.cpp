// The renderer factory; see renderer_factory.hpp.
#include "engine/render/renderer_factory.hpp"

#include <algorithm>
#include <cctype>
#include <string>

#include "engine/render/exact_renderer.hpp"
#include "engine/render/upsampled_renderer.hpp"

namespace stampede {

const char* renderer_kind_name(RendererKind kind) {
  switch (kind) {
    case RendererKind::kUpsampled: return "upsampled";
    case RendererKind::kExact: return "exact";
    case RendererKind::kAuto: return "auto";
  }
  return "?";
}

bool parse_renderer_kind(std::string_view name, RendererKind* out) {
  std::string s(name);
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (RendererKind k : {RendererKind::kUpsampled, RendererKind::kExact, RendererKind::kAuto})
    if (s == renderer_kind_name(k)) {
      *out = k;
      return true;
    }
  return false;
}

const char* renderer_kind_names() { return "auto, exact, upsampled"; }


std::unique_ptr<Renderer> make_renderer(RendererKind kind, const RenderOptions& render, const ModelOptions& model,
                                        FftPlanCache& plans) {
  switch (kind) {
    case RendererKind::kUpsampled: return std::make_unique<UpsampledRenderer>(render, model, nullptr, plans);
    case RendererKind::kExact:
    case RendererKind::kAuto: return std::make_unique<ExactRenderer>(render, model);
  }
  throw std::invalid_argument("make_renderer: unknown renderer kind");
}

}  // namespace stampede
