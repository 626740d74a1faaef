// The mesh I/O suite's shared parts: independent counts from file text, two tetrahedra and their comparison, files
// of each format built by hand from the specifications (MSH 2.2 and 4.1, VTK 5.1, VTU variants, PLY, glTF), and
// the checks that a parser or a damaged file is refused with one sentence.
#pragma once
#include <rehearse/simcore/meshio.hpp>

#include <QString>

#include <cstddef>
#include <functional>
#include <string>
#include <string_view>

// Independent counts from the file text: points declared by a VTK header.
std::size_t vtkDeclaredPoints(const std::string& bytes);

// Vertices an OBJ's faces actually use, counted from the text (assimp drops unused ones).
std::size_t objUsedVertices(const std::string& text);

rehearse::simcore::Mesh twoTets();

void compareMeshes(const rehearse::simcore::Mesh& a, const rehearse::simcore::Mesh& b, bool withTriangles = true);

template <class T>
void putLE(std::string& s, T v) {
  s.append(reinterpret_cast<const char*>(&v), sizeof v);
}

// MSH 2.2 binary of twoTets (hand-built from the format specification).
std::string msh22Binary(const rehearse::simcore::Mesh& m);

// MSH 4.1 (ascii or binary) of twoTets: one volume entity per label with a physical tag.
std::string msh41(const rehearse::simcore::Mesh& m, bool binary);

std::string vtk51Ascii(const rehearse::simcore::Mesh& m);

std::string base64(const std::string& in);

// VTU with zlib-compressed inline arrays (UInt32 headers), or raw appended data (UInt64 headers).
std::string vtuVariant(const rehearse::simcore::Mesh& m, bool compressed);

// Every parser must throw MeshError (never crash) on these.
void expectRefused(const std::function<rehearse::simcore::Mesh(std::string_view)>& parse, const std::string& bytes,
                   const char* what);

// Triangle primitives (mode 4, the default) of a binary glTF, read from its JSON chunk (bytes 20 on).
int glbTrianglePrimitives(const std::string& glb);

// A damaged file is refused by loadMesh with one sentence that names the file and contains `expect`, and (when
// `cli`) `rehearse info` on it exits 1-123, without a signal, within 60 s, printing one line on stderr.
void expectFileRefused(const std::string& file, const std::string& bytes, const QString& expect, bool cli = true,
                       const rehearse::simcore::LoadOptions& options = {});

std::string plyHeader(const char* format, int vertices, int faces, const char* listType = "uchar int");

// A .gltf of `nodes` (JSON text of the nodes array) and one triangle mesh whose accessor has no buffer (zeros).
std::string gltfWith(const std::string& nodes, const std::string& roots = "[0]", const std::string& extra = "");
