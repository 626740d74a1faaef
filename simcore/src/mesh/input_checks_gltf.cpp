// glTF and GLB pre-parse checks (see input_checks.hpp): the GLB chunks, buffers, buffer views, accessors,
// meshes and their primitives, the node hierarchy, and the index values in a GLB's binary chunk.
#include <rehearse/simcore/input_checks.hpp>

#include "input_checks_parts.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace rehearse::simcore::checks {

using namespace detail;

namespace {

using IndexChecks = std::vector<std::pair<long long, long long>>;  // (indices accessor, position accessor)

int jsonIndex(const nlohmann::json& o, const char* key, std::size_t size, long long& out) {
  // 0: absent, 1: valid, -1: out of range or not an index.
  if (!o.is_object() || !o.contains(key)) return 0;
  const auto& v = o.at(key);
  if (!v.is_number_integer()) return -1;
  out = v.get<long long>();
  return out >= 0 && static_cast<std::size_t>(out) < size ? 1 : -1;
}

double jsonNumber(const nlohmann::json& o, const char* key, double fallback) {
  if (!o.is_object() || !o.contains(key) || !o.at(key).is_number()) return fallback;
  return o.at(key).get<double>();
}

int componentBytes(double t) {
  return t == 5120 || t == 5121 ? 1 : t == 5122 || t == 5123 ? 2 : t == 5125 || t == 5126 ? 4 : 0;
}

int componentCount(const nlohmann::json& a) {
  static const std::map<std::string, int> n = {{"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3}, {"VEC4", 4},
                                               {"MAT2", 4},   {"MAT3", 9}, {"MAT4", 16}};
  if (!a.contains("type") || !a.at("type").is_string()) return 0;
  auto it = n.find(a.at("type").get<std::string>());
  return it == n.end() ? 0 : it->second;
}

// Each buffer's byteLength against the binary chunk, its embedded data or its file.
std::string gltfBuffersProblem(const nlohmann::json& buffers, bool binary, bool haveBin, std::string_view bin,
                               const std::function<long long(const std::string& uri)>& externalBytes) {
  for (std::size_t b = 0; b < buffers.size(); ++b) {
    const double length = jsonNumber(buffers[b], "byteLength", -1);
    if (!(length >= 0)) return "its buffer " + num(static_cast<double>(b)) + " has no valid byteLength";
    if (binary && b == 0 && !buffers[b].contains("uri") && (!haveBin || length > static_cast<double>(bin.size())))
      return "its buffer 0 declares " + num(length) + " bytes but the binary chunk holds " + num(static_cast<double>(bin.size()));
    // A buffer's own file, or its embedded base64, must hold what it declares (assimp read past a short one).
    if (buffers[b].is_object() && buffers[b].contains("uri") && buffers[b]["uri"].is_string()) {
      const std::string uri = buffers[b]["uri"].get<std::string>();
      double held = -1;
      std::string where;
      if (uri.rfind("data:", 0) == 0) {
        const auto comma = uri.find(',');
        if (comma == std::string::npos || uri.find(";base64", 0) > comma)
          return "its buffer " + num(static_cast<double>(b)) + " embeds data that is not base64";
        const std::size_t chars = uri.size() - comma - 1;
        std::size_t pad = 0;
        for (std::size_t i = uri.size(); i > comma + 1 && uri[i - 1] == '='; --i) ++pad;
        held = static_cast<double>(chars / 4 * 3) - static_cast<double>(std::min<std::size_t>(pad, 2));
        where = "its embedded data";
      } else if (externalBytes) {
        const long long size = externalBytes(uri);
        if (size < 0)
          return "its buffer " + num(static_cast<double>(b)) + " names the file '" + uri.substr(0, 60) +
                 "', which is not a file beside it";
        held = static_cast<double>(size);
        where = "the file '" + uri.substr(0, 60) + "'";
      }
      if (held >= 0 && length > held)
        return "its buffer " + num(static_cast<double>(b)) + " declares " + num(length) + " bytes but " + where +
               " holds " + num(held);
    }
  }
  return {};
}

// Each buffer view within its buffer.
std::string gltfViewsProblem(const nlohmann::json& views, const nlohmann::json& buffers) {
  for (std::size_t v = 0; v < views.size(); ++v) {
    long long b = 0;
    if (jsonIndex(views[v], "buffer", buffers.size(), b) != 1)
      return "its buffer view " + num(static_cast<double>(v)) + " refers to a buffer it does not have";
    const double offset = jsonNumber(views[v], "byteOffset", 0), length = jsonNumber(views[v], "byteLength", -1);
    if (!(offset >= 0 && length >= 0 &&
          offset + length <= jsonNumber(buffers[static_cast<std::size_t>(b)], "byteLength", -1)))
      return "its buffer view " + num(static_cast<double>(v)) + " reaches beyond the end of its buffer";
  }
  return {};
}

// Each accessor's values within its buffer view.
std::string gltfAccessorsProblem(const nlohmann::json& accessors, const nlohmann::json& views) {
  for (std::size_t a = 0; a < accessors.size(); ++a) {
    const auto& acc = accessors[a];
    const double count = jsonNumber(acc, "count", -1);
    const int cb = componentBytes(jsonNumber(acc, "componentType", 0)), nc = acc.is_object() ? componentCount(acc) : 0;
    const std::string what = "its accessor " + num(static_cast<double>(a));
    if (!(count >= 1) || cb == 0 || nc == 0) return what + " has no valid count, componentType or type";
    long long v = 0;
    const int hasView = jsonIndex(acc, "bufferView", views.size(), v);
    if (hasView == -1) return what + " refers to a buffer view it does not have";
    if (hasView == 0) continue;  // zeros (or sparse values)
    const auto& view = views[static_cast<std::size_t>(v)];
    const double element = cb * nc, stride = jsonNumber(view, "byteStride", element);
    if (!(stride >= element) || jsonNumber(acc, "byteOffset", 0) < 0 ||
        jsonNumber(acc, "byteOffset", 0) + stride * (count - 1) + element > jsonNumber(view, "byteLength", -1))
      return what + " declares " + num(count) + " values, more than its buffer view holds";
  }
  return {};
}

// The primitives of each mesh: their accessors, the triangles they make, the index accessors to check.
std::string gltfMeshesProblem(const nlohmann::json& meshes, const nlohmann::json& accessors,
                              std::vector<double>& meshTriangles, IndexChecks& indexChecks) {
  for (std::size_t m = 0; m < meshes.size(); ++m) {
    if (!meshes[m].is_object() || !meshes[m].contains("primitives") || !meshes[m].at("primitives").is_array()) continue;
    for (const auto& p : meshes[m].at("primitives")) {
      long long pa = 0, ia = 0;
      const nlohmann::json attributes = p.is_object() && p.contains("attributes") ? p.at("attributes") : nlohmann::json::object();
      const int hasPosition = jsonIndex(attributes, "POSITION", accessors.size(), pa);
      const int hasIndices = jsonIndex(p, "indices", accessors.size(), ia);
      if (hasPosition == -1 || hasIndices == -1)
        return "its mesh " + num(static_cast<double>(m)) + " refers to an accessor it does not have";
      if (hasPosition == 0) continue;
      const double corners = jsonNumber(accessors[static_cast<std::size_t>(hasIndices == 1 ? ia : pa)], "count", 0);
      const double mode = jsonNumber(p, "mode", 4);
      meshTriangles[m] += mode == 4 ? std::floor(corners / 3) : mode == 5 || mode == 6 ? std::max(0.0, corners - 2) : 0;
      if (hasIndices == 1) indexChecks.emplace_back(ia, pa);
    }
  }
  return {};
}

// The nodes' meshes and children, and the roots of the hierarchy (the scenes' nodes, or every node no one's child).
std::string gltfRootsProblem(const nlohmann::json& nodes, const nlohmann::json& meshes, const nlohmann::json& scenes,
                             std::vector<std::size_t>& roots) {
  const std::size_t n = nodes.size();
  std::vector<bool> child(n, false);
  for (std::size_t i = 0; i < n; ++i) {
    long long m = 0;
    if (jsonIndex(nodes[i], "mesh", meshes.size(), m) == -1)
      return "its node " + num(static_cast<double>(i)) + " refers to a mesh it does not have";
    if (!nodes[i].is_object() || !nodes[i].contains("children")) continue;
    const auto& c = nodes[i].at("children");
    if (!c.is_array()) return "its node " + num(static_cast<double>(i)) + " has children that are not a list";
    for (const auto& k : c) {
      if (!k.is_number_integer() || k.get<long long>() < 0 || static_cast<std::size_t>(k.get<long long>()) >= n)
        return "its node " + num(static_cast<double>(i)) + " has a child it does not have";
      child[static_cast<std::size_t>(k.get<long long>())] = true;
    }
  }
  for (const auto& s : scenes)
    if (s.is_object() && s.contains("nodes") && s.at("nodes").is_array())
      for (const auto& r : s.at("nodes")) {
        if (!r.is_number_integer() || r.get<long long>() < 0 || static_cast<std::size_t>(r.get<long long>()) >= n)
          return "its scene refers to a node it does not have";
        roots.push_back(static_cast<std::size_t>(r.get<long long>()));
      }
  if (scenes.empty())
    for (std::size_t i = 0; i < n; ++i)
      if (!child[i]) roots.push_back(i);
  return {};
}

// The mesh instances and triangles the hierarchy places from its roots: no cycle, not too deep, not too many.
std::string gltfPlacementProblem(const nlohmann::json& nodes, const nlohmann::json& meshes,
                                 const std::vector<double>& meshTriangles, const std::vector<std::size_t>& roots) {
  const std::size_t n = nodes.size();
  // Instances and triangles reached below each node, memoised (a DAG of shared levels multiplies them).
  std::vector<int> state(n, 0);  // 0 unseen, 1 on the current path, 2 done
  std::vector<double> instances(n, 0), triangles(n, 0);
  double totalInstances = 0, totalTriangles = 0;
  for (std::size_t root : roots) {
    std::vector<std::pair<std::size_t, std::size_t>> path;  // node, next child
    if (state[root] == 0) path.emplace_back(root, 0), state[root] = 1;
    while (!path.empty()) {
      if (static_cast<int>(path.size()) > kMaxGltfDepth)
        return "its node hierarchy is more than " + num(kMaxGltfDepth) + " levels deep";
      auto& [node, next] = path.back();
      const nlohmann::json* c = nodes[node].is_object() && nodes[node].contains("children") ? &nodes[node].at("children") : nullptr;
      if (c && next < c->size()) {
        const auto k = static_cast<std::size_t>((*c)[next++].get<long long>());
        if (state[k] == 1) return "its node hierarchy has a cycle (node " + num(static_cast<double>(k)) + " is its own ancestor)";
        if (state[k] == 0) path.emplace_back(k, 0), state[k] = 1;
        continue;
      }
      long long m = 0;
      double inst = 0, tri = 0;
      if (jsonIndex(nodes[node], "mesh", meshes.size(), m) == 1)
        inst = 1, tri = meshTriangles[static_cast<std::size_t>(m)];
      if (c)
        for (const auto& k : *c) {
          inst += instances[static_cast<std::size_t>(k.get<long long>())];
          tri += triangles[static_cast<std::size_t>(k.get<long long>())];
        }
      instances[node] = std::min(inst, 1e300);
      triangles[node] = std::min(tri, 1e300);
      state[node] = 2;
      path.pop_back();
    }
    totalInstances += instances[root];
    totalTriangles += triangles[root];
  }
  if (totalInstances > kMaxGltfInstances)
    return "its node hierarchy places " + num(totalInstances) + " mesh instances (at most " + num(kMaxGltfInstances) + ")";
  if (totalTriangles > kMaxSurfaceItems)
    return "its node hierarchy places " + num(totalTriangles) + " triangles (at most " + num(kMaxSurfaceItems) + ")";
  return {};
}

// Index values against the vertex count, read from the GLB's binary chunk.
std::string gltfIndexValuesProblem(const nlohmann::json& accessors, const nlohmann::json& views,
                                   const nlohmann::json& buffers, std::string_view bin,
                                   const IndexChecks& indexChecks) {
  for (auto [ia, pa] : indexChecks) {
    const auto& acc = accessors[static_cast<std::size_t>(ia)];
    long long v = 0;
    if (jsonIndex(acc, "bufferView", views.size(), v) != 1 || acc.contains("sparse")) continue;
    const auto& view = views[static_cast<std::size_t>(v)];
    long long b = 0;
    if (jsonIndex(view, "buffer", buffers.size(), b) != 1 || b != 0 || buffers[0].contains("uri")) continue;
    const int cb = componentBytes(jsonNumber(acc, "componentType", 0));
    const double vertices = jsonNumber(accessors[static_cast<std::size_t>(pa)], "count", 0);
    const double stride = jsonNumber(view, "byteStride", cb);
    const double first = jsonNumber(view, "byteOffset", 0) + jsonNumber(acc, "byteOffset", 0);
    if (!(stride >= 0 && stride <= static_cast<double>(bin.size()) && first >= 0 &&
          first <= static_cast<double>(bin.size())))
      return "its accessor " + num(static_cast<double>(ia)) + " reaches beyond the binary chunk";
    const auto start = static_cast<std::size_t>(first);
    const auto count = static_cast<std::size_t>(jsonNumber(acc, "count", 0));
    for (std::size_t i = 0; i < count; ++i) {
      const std::size_t at = start + i * static_cast<std::size_t>(stride);
      if (at + static_cast<std::size_t>(cb) > bin.size()) return "its accessor " + num(static_cast<double>(ia)) + " reaches beyond the binary chunk";
      std::uint32_t value = 0;
      std::memcpy(&value, bin.data() + at, static_cast<std::size_t>(cb));  // glTF is little-endian
      if (value >= vertices)
        return "its accessor " + num(static_cast<double>(ia)) + " holds vertex index " + num(value) + ", but the mesh has " +
               plural(vertices, "vertice");
    }
  }
  return {};
}

}  // namespace

std::string gltfProblem(std::string_view bytes, bool binary,
                        const std::function<long long(const std::string& uri)>& externalBytes) {
  std::string_view json = bytes, bin;
  bool haveBin = false;
  auto u32 = [&](std::size_t at) {
    std::uint32_t v = 0;
    std::memcpy(&v, bytes.data() + at, 4);
    return v;
  };
  if (binary) {
    if (bytes.size() < 20 || bytes.substr(0, 4) != "glTF") return {};  // assimp says it is not a GLB
    const std::uint32_t jsonLength = u32(12);
    if (u32(16) != 0x4E4F534Au || jsonLength > bytes.size() - 20) return "its JSON chunk is longer than the file";
    json = bytes.substr(20, jsonLength);
    std::size_t at = 20 + static_cast<std::size_t>(jsonLength);
    at = (at + 3) & ~std::size_t(3);
    if (at + 8 <= bytes.size() && u32(at + 4) == 0x004E4942u) {
      const std::uint32_t binLength = u32(at);
      if (binLength > bytes.size() - at - 8) return "its binary chunk is longer than the file";
      bin = bytes.substr(at + 8, binLength);
      haveBin = true;
    }
  }
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(json.begin(), json.end());
  } catch (const std::exception&) {
    return {};  // not JSON: assimp says so
  }
  if (!j.is_object()) return {};
  auto array = [&](const char* key) -> const nlohmann::json& {
    static const nlohmann::json empty = nlohmann::json::array();
    auto it = j.find(key);
    return it != j.end() && it->is_array() ? *it : empty;
  };
  const auto &nodes = array("nodes"), &meshes = array("meshes"), &accessors = array("accessors"),
             &views = array("bufferViews"), &buffers = array("buffers"), &scenes = array("scenes");
  // Buffers, views, accessors.
  if (auto problem = gltfBuffersProblem(buffers, binary, haveBin, bin, externalBytes); !problem.empty()) return problem;
  if (auto problem = gltfViewsProblem(views, buffers); !problem.empty()) return problem;
  if (auto problem = gltfAccessorsProblem(accessors, views); !problem.empty()) return problem;
  // The hierarchy: each path from a root, iteratively (a 20,000-deep chain must not overflow our stack either).
  std::vector<double> meshTriangles(meshes.size(), 0.0);
  std::vector<std::pair<long long, long long>> indexChecks;  // (indices accessor, position accessor)
  if (auto problem = gltfMeshesProblem(meshes, accessors, meshTriangles, indexChecks); !problem.empty()) return problem;
  std::vector<std::size_t> roots;
  if (auto problem = gltfRootsProblem(nodes, meshes, scenes, roots); !problem.empty()) return problem;
  if (auto problem = gltfPlacementProblem(nodes, meshes, meshTriangles, roots); !problem.empty()) return problem;
  // Index values against the vertex count, where the bytes are at hand (the GLB's binary chunk).
  if (haveBin) return gltfIndexValuesProblem(accessors, views, buffers, bin, indexChecks);
  return {};
}

}  // namespace rehearse::simcore::checks
