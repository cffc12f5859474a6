// The pipe format, PLY stream v1 (docs/formats.md): zero or more complete PLY
// documents back to back; one document = one view (points) or one mesh. Metadata travels as
// `comment rgbd:<key> <values>` lines. Writers emit binary_little_endian; readers accept
// ASCII, binary big- and little-endian, float and double coordinates.
#pragma once

#include <cstddef>
#include <iosfwd>
#include <string>

#include "toolkit/mesh.hpp"
#include "toolkit/point_cloud.hpp"

namespace rgbd::io {

enum class DocumentKind { kPoints, kMesh };

/// One document of a stream. For meshes, `cloud.view` carries the metadata and `mesh` the
/// geometry (with "v:color" / "v:normal" when present); `cloud.points` stays empty.
struct Document {
    DocumentKind kind = DocumentKind::kPoints;
    PointCloud cloud;
    Mesh mesh;
};

/// Reads documents one at a time from a stream (a file or stdin).
class PlyStreamReader {
public:
    /// `name` is used in error messages ("<stdin>" or the file path).
    PlyStreamReader(std::istream& in, std::string name);

    /// Reads the next document. Returns false at a clean end of stream (EOF before a new
    /// header). Throws InputError "NAME: document K: problem" for garbage, a truncated
    /// document, NaN/inf coordinates, or a header without vertices.
    bool next(Document& document);

    /// Number of documents read so far.
    std::size_t count() const { return count_; }
    const std::string& name() const { return name_; }

private:
    std::istream& in_;
    std::string name_;
    std::size_t count_ = 0;
};

/// Writes one point document (binary little-endian) with all properties of the point set,
/// normals as nx ny nz, and the rgbd: metadata of cloud.view (first line `rgbd:stream 1`).
void write_points(std::ostream& out, const PointCloud& cloud);

/// Writes one mesh document (binary little-endian): vertices with colour and normal when
/// present, faces as vertex_indices lists; metadata from `view`.
void write_mesh(std::ostream& out, const Mesh& mesh, const ViewInfo& view);

/// Writes a document of either kind.
void write_document(std::ostream& out, const Document& document);

/// The `comment` lines (without "comment ") that encode a ViewInfo, first `rgbd:stream 1`.
std::vector<std::string> view_to_comments(const ViewInfo& view, DocumentKind kind);
/// Parses comment lines back into a ViewInfo; unknown rgbd: keys and foreign comments go to
/// extra_comments. Throws InputError on a malformed known key.
ViewInfo view_from_comments(const std::vector<std::string>& comments);

}  // namespace rgbd::io
