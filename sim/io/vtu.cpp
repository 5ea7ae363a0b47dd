// vtu.cpp - VTK XML unstructured grid writer and reader (see vtu.h).
#include "sim/io/vtu.h"

#include <unistd.h>

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "sim/core_error.h"
#include "sim/message_text.h"

namespace esim {

namespace {

constexpr char kB64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

std::string base64Encode(const std::vector<std::uint8_t>& in) {
  std::string out;
  out.reserve((in.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const std::uint32_t v = (in[i] << 16) | (in[i + 1] << 8) | in[i + 2];
    out += kB64[(v >> 18) & 63];
    out += kB64[(v >> 12) & 63];
    out += kB64[(v >> 6) & 63];
    out += kB64[v & 63];
  }
  if (i < in.size()) {
    std::uint32_t v = in[i] << 16;
    if (i + 1 < in.size()) v |= in[i + 1] << 8;
    out += kB64[(v >> 18) & 63];
    out += kB64[(v >> 12) & 63];
    out += i + 1 < in.size() ? kB64[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

std::vector<std::uint8_t> base64Decode(const std::string& in) {
  int table[256];
  for (int& t : table) t = -1;
  for (int k = 0; k < 64; ++k) table[static_cast<unsigned char>(kB64[k])] = k;
  std::vector<std::uint8_t> out;
  std::uint32_t acc = 0;
  int bits = 0;
  for (unsigned char c : in) {
    if (table[c] < 0) continue;  // whitespace and '=' padding
    acc = (acc << 6) | table[c];
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<std::uint8_t>((acc >> bits) & 0xff));
    }
  }
  return out;
}

// base64 of [uint64 byte count][raw little-endian data]
template <typename T>
std::string encodeArray(const std::vector<T>& data) {
  const std::uint64_t bytes = data.size() * sizeof(T);
  std::vector<std::uint8_t> raw(sizeof(bytes) + bytes);
  std::memcpy(raw.data(), &bytes, sizeof(bytes));
  if (bytes) std::memcpy(raw.data() + sizeof(bytes), data.data(), bytes);
  return base64Encode(raw);
}

void writeDataArray(std::ostream& os, const char* type, const std::string& name, int components,
                    const std::string& payload) {
  os << "        <DataArray type=\"" << type << "\" Name=\"" << name << "\" NumberOfComponents=\""
     << components << "\" format=\"binary\">\n          " << payload << "\n        </DataArray>\n";
}

std::string attribute(const std::string& tag, const std::string& key) {
  const std::string pat = key + "=\"";
  const size_t p = tag.find(pat);
  if (p == std::string::npos) return "";
  const size_t q = tag.find('"', p + pat.size());
  return tag.substr(p + pat.size(), q - p - pat.size());
}

// a double as text for messages (any value, NaN and huge ones included)
std::string formatValue(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// a non-negative whole number of at most `limit` in an attribute (e.g. NumberOfComponents)
std::size_t parseCount(const std::string& text, std::size_t limit, const std::string& what,
                       const std::string& path) {
  std::size_t n = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, n);
  ESIM_VERIFY(ec == std::errc() && ptr == end && n <= limit,
              path + ": " + what + " " + quoteInMessage(text) + " is not a whole number in [0, " +
                  std::to_string(limit) + "]");
  return n;
}

// decodes one DataArray body into doubles; every value of the body or none
std::vector<double> decodeArray(const std::string& type, const std::string& format,
                                const std::string& body, const std::string& label,
                                const std::string& path) {
  const std::string where = path + ": " + label;
  std::vector<double> out;
  if (format == "ascii") {
    std::istringstream is(body);
    double v;
    while (is >> v) out.push_back(v);
    ESIM_VERIFY(is.eof(), where + ": value " + std::to_string(out.size() + 1) +
                              " is not a number; expected ascii numbers separated by spaces");
    return out;
  }
  ESIM_VERIFY(format == "binary", where + ": format " + quoteInMessage(format) +
                                      " is not supported; expected 'binary' or 'ascii'");
  const auto raw = base64Decode(body);
  ESIM_VERIFY(raw.size() >= 8, where + " is truncated (no UInt64 byte count)");
  std::uint64_t bytes;
  std::memcpy(&bytes, raw.data(), 8);
  ESIM_VERIFY(bytes == raw.size() - 8, where + " holds " + std::to_string(raw.size() - 8) +
                                           " bytes but its header says " + std::to_string(bytes));
  const std::uint8_t* p = raw.data() + 8;
  auto read = [&](auto tag) {
    using T = decltype(tag);
    ESIM_VERIFY(bytes % sizeof(T) == 0, where + ": " + std::to_string(bytes) +
                                            " bytes are not a whole number of " + type + " values");
    const size_t n = bytes / sizeof(T);
    out.resize(n);
    for (size_t i = 0; i < n; ++i) {
      T v;
      std::memcpy(&v, p + i * sizeof(T), sizeof(T));
      out[i] = static_cast<double>(v);
    }
  };
  if (type == "Float64")
    read(double{});
  else if (type == "Float32")
    read(float{});
  else if (type == "Int64")
    read(std::int64_t{});
  else if (type == "Int32")
    read(std::int32_t{});
  else if (type == "UInt8")
    read(std::uint8_t{});
  else if (type == "UInt64")
    read(std::uint64_t{});
  else
    throw Error(where + ": type " + quoteInMessage(type) + " is not supported");
  return out;
}

// an index read as a double (ascii or any integer type): a whole number in [0, size)
bool isIndex(double v, std::size_t size) {
  return v >= 0 && v < static_cast<double>(size) && v == std::floor(v);
}

}  // namespace

const VtuField* VtuData::findPointField(const std::string& name) const {
  for (const auto& f : pointData)
    if (f.name == name) return &f;
  return nullptr;
}

const VtuField* VtuData::findCellField(const std::string& name) const {
  for (const auto& f : cellData)
    if (f.name == name) return &f;
  return nullptr;
}

void writeVtu(const std::string& path, const TetMesh& mesh, const std::vector<VtuField>& pointData,
              const std::vector<VtuField>& cellData) {
  // ---- validate field sizes ----
  for (const auto& f : pointData)
    ESIM_VERIFY(f.values.size() == static_cast<size_t>(f.components) * mesh.numNodes(),
                path + ": point field " + quoteInMessage(f.name) + " has " +
                    std::to_string(f.values.size()) + " values; expected " +
                    std::to_string(f.components * mesh.numNodes()));
  for (const auto& f : cellData)
    ESIM_VERIFY(f.values.size() == static_cast<size_t>(f.components) * mesh.numTets(),
                path + ": cell field " + quoteInMessage(f.name) + " has " +
                    std::to_string(f.values.size()) + " values; expected " +
                    std::to_string(f.components * mesh.numTets()));
  std::vector<int> cells;
  for (int e = 0; e < mesh.numTets(); ++e)
    if (mesh.isAlive(e)) cells.push_back(e);

  // ---- arrays ----
  std::vector<double> points(3 * mesh.nodes.size());
  for (int i = 0; i < mesh.numNodes(); ++i)
    for (int c = 0; c < 3; ++c) points[3 * i + c] = mesh.nodes[i][c];
  std::vector<std::int64_t> conn, offsets;
  std::vector<std::uint8_t> types(cells.size(), 10);
  std::vector<double> tet_id;
  for (int e : cells) {
    for (int v : mesh.tets[e]) conn.push_back(v);
    offsets.push_back(static_cast<std::int64_t>(conn.size()));
    tet_id.push_back(e);
  }

  // beside the target, named by this process (a user's NAME.vtu.tmp is never touched), and
  // renamed onto it only when whole
  const std::string tmp = path + ".tmp" + std::to_string(::getpid());
  {
    std::ofstream os(tmp, std::ios::binary);
    ESIM_VERIFY(os.good(), path + ": cannot open for writing");
    os << "<?xml version=\"1.0\"?>\n"
       << "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" "
          "header_type=\"UInt64\">\n"
       << "  <UnstructuredGrid>\n"
       << "    <Piece NumberOfPoints=\"" << mesh.numNodes() << "\" NumberOfCells=\"" << cells.size()
       << "\">\n";
    os << "      <Points>\n";
    writeDataArray(os, "Float64", "Points", 3, encodeArray(points));
    os << "      </Points>\n      <Cells>\n";
    writeDataArray(os, "Int64", "connectivity", 1, encodeArray(conn));
    writeDataArray(os, "Int64", "offsets", 1, encodeArray(offsets));
    writeDataArray(os, "UInt8", "types", 1, encodeArray(types));
    os << "      </Cells>\n      <PointData>\n";
    for (const auto& f : pointData)
      writeDataArray(os, "Float64", f.name, f.components, encodeArray(f.values));
    os << "      </PointData>\n      <CellData>\n";
    writeDataArray(os, "Float64", "tet_id", 1, encodeArray(tet_id));
    for (const auto& f : cellData) {
      std::vector<double> alive_values;
      alive_values.reserve(cells.size() * f.components);
      for (int e : cells)
        for (int c = 0; c < f.components; ++c)
          alive_values.push_back(f.values[e * f.components + c]);
      writeDataArray(os, "Float64", f.name, f.components, encodeArray(alive_values));
    }
    os << "      </CellData>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n";
    os.close();
    if (!os) {
      std::remove(tmp.c_str());
      throw Error(path + ": write failed (disk full?)");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {  // (the temporary file was left beside a folder named `path`)
    const std::string why = ec.message();
    std::filesystem::remove(tmp, ec);
    throw Error(path + ": cannot write it: " + why);
  }
}

VtuData readVtu(const std::string& path) {
  std::error_code ec;
  ESIM_VERIFY(std::filesystem::exists(path, ec), path + ": file not found");
  // (a device such as /dev/zero was read until memory ran out)
  ESIM_VERIFY(std::filesystem::is_regular_file(path, ec),
              path + ": cannot read the .vtu: not a regular file");
  std::ifstream is(path, std::ios::binary);
  ESIM_VERIFY(is.good(), path + ": not readable");
  std::stringstream ss;
  ss << is.rdbuf();
  const std::string text = ss.str();
  ESIM_VERIFY(text.find("type=\"UnstructuredGrid\"") != std::string::npos,
              path + ": not a VTK XML UnstructuredGrid file");
  ESIM_VERIFY(text.find("compressor=") == std::string::npos,
              path + ": compressed VTU is not supported; write it uncompressed");
  const std::string header_type =
      attribute(text.substr(0, text.find('>', text.find("<VTKFile"))), "header_type");
  ESIM_VERIFY(
      header_type.empty() || header_type == "UInt64",
      path + ": header_type " + quoteInMessage(header_type) + " is not supported; expected UInt64");

  VtuData data;
  std::vector<double> conn, offsets, types;
  bool hasPoints = false, hasConn = false, hasOffsets = false, hasTypes = false;
  int pieces = 0;
  std::string piecePoints, pieceCells;  // the Piece's NumberOfPoints / NumberOfCells
  // walk the sections in order, tracking which block each DataArray is in
  enum class Block { None, Points, Cells, PointData, CellData } block = Block::None;
  size_t pos = 0;
  while (true) {
    const size_t lt = text.find('<', pos);
    if (lt == std::string::npos) break;
    const size_t gt = text.find('>', lt);
    ESIM_VERIFY(gt != std::string::npos, path + ": truncated XML");
    const std::string tag = text.substr(lt, gt - lt + 1);
    pos = gt + 1;
    if (tag.rfind("<Piece", 0) == 0) {
      ESIM_VERIFY(++pieces == 1, path + ": more than one Piece; expected a single Piece");
      piecePoints = attribute(tag, "NumberOfPoints");
      pieceCells = attribute(tag, "NumberOfCells");
    } else if (tag.rfind("<Points", 0) == 0) {
      block = Block::Points;
    } else if (tag.rfind("<Cells", 0) == 0) {
      block = Block::Cells;
    } else if (tag.rfind("<PointData", 0) == 0) {
      block = Block::PointData;
    } else if (tag.rfind("<CellData", 0) == 0) {
      block = Block::CellData;
    } else if (tag.rfind("</", 0) == 0 && tag.find("DataArray") == std::string::npos) {
      block = Block::None;
    }
    if (tag.rfind("<DataArray", 0) != 0) continue;
    const size_t end = text.find("</DataArray>", pos);
    ESIM_VERIFY(end != std::string::npos, path + ": DataArray without closing tag");
    const std::string name = attribute(tag, "Name");
    const std::string comps = attribute(tag, "NumberOfComponents");
    const int components =
        comps.empty() ? 1
                      : static_cast<int>(parseCount(comps, 1 << 20, "NumberOfComponents", path));
    ESIM_VERIFY(components >= 1,
                path + ": DataArray " + quoteInMessage(name) + " has 0 components");
    // (an array without a Name, usually the Points', is named by its block in messages)
    const std::string label = !name.empty()            ? "DataArray " + quoteInMessage(name)
                              : block == Block::Points ? std::string("the Points' DataArray")
                                                       : std::string("a DataArray without a Name");
    auto values = decodeArray(attribute(tag, "type"), attribute(tag, "format"),
                              text.substr(pos, end - pos), label, path);
    pos = end + 12;
    auto once = [&](bool& seen, const char* what) {
      ESIM_VERIFY(!seen, path + ": more than one " + what + " array");
      seen = true;
    };
    switch (block) {
      case Block::Points:
        once(hasPoints, "Points");
        ESIM_VERIFY(components == 3 && values.size() % 3 == 0,
                    path + ": Points must have 3 components (NumberOfComponents=\"" + comps +
                        "\", " + std::to_string(values.size()) + " values)");
        for (size_t i = 0; i < values.size(); i += 3)
          data.points.emplace_back(values[i], values[i + 1], values[i + 2]);
        break;
      case Block::Cells:
        if (name == "connectivity") {
          once(hasConn, "connectivity");
          conn = std::move(values);
        } else if (name == "offsets") {
          once(hasOffsets, "offsets");
          offsets = std::move(values);
        } else if (name == "types") {
          once(hasTypes, "types");
          types = std::move(values);
        }
        break;
      case Block::PointData:
        data.pointData.push_back({name, components, std::move(values)});
        break;
      case Block::CellData:
        data.cellData.push_back({name, components, std::move(values)});
        break;
      case Block::None:
        break;
    }
  }
  // cells: offsets 4, 8, ... up to the end of the connectivity, one type 10 per cell
  ESIM_VERIFY(types.size() == offsets.size(), path + ": " + std::to_string(types.size()) +
                                                  " cell types for " +
                                                  std::to_string(offsets.size()) + " cell offsets");
  for (double t : types)
    ESIM_VERIFY(t == 10, path + ": cell type " + formatValue(t) +
                             " found; only tetrahedra (VTK type 10) are supported");
  size_t prev = 0;
  for (double o : offsets) {
    ESIM_VERIFY(o == static_cast<double>(prev + 4) && prev + 4 <= conn.size(),
                path +
                    ": cell offsets are not those of tetrahedra (4 nodes per cell) in a "
                    "connectivity of " +
                    std::to_string(conn.size()) + " entries: " + formatValue(o) + " follows " +
                    std::to_string(prev));
    Tet t;
    for (int k = 0; k < 4; ++k) {
      const double v = conn[prev + k];
      ESIM_VERIFY(isIndex(v, data.points.size()),
                  path + ": cell refers to node " + formatValue(v) + " outside the " +
                      std::to_string(data.points.size()) + " points");
      t[k] = static_cast<int>(v);
    }
    data.tets.push_back(t);
    prev += 4;
  }
  ESIM_VERIFY(prev == conn.size(), path + ": the connectivity has " + std::to_string(conn.size()) +
                                       " entries but the cells use " + std::to_string(prev));
  // the Piece's counts, and one value (of each component) per point or cell in every field
  if (!piecePoints.empty())
    ESIM_VERIFY(parseCount(piecePoints, SIZE_MAX, "NumberOfPoints", path) == data.points.size(),
                path + ": NumberOfPoints=\"" + piecePoints + "\" but " +
                    std::to_string(data.points.size()) + " points");
  if (!pieceCells.empty())
    ESIM_VERIFY(parseCount(pieceCells, SIZE_MAX, "NumberOfCells", path) == data.tets.size(),
                path + ": NumberOfCells=\"" + pieceCells + "\" but " +
                    std::to_string(data.tets.size()) + " cells");
  auto checkCounts = [&](const std::vector<VtuField>& fields, size_t count, const char* kind) {
    for (const VtuField& f : fields)
      ESIM_VERIFY(f.values.size() == static_cast<size_t>(f.components) * count,
                  path + ": " + kind + " data " + quoteInMessage(f.name) + " has " +
                      std::to_string(f.values.size()) + " values; expected " +
                      std::to_string(f.components) + " per " + kind + " for " +
                      std::to_string(count) + " " + kind + "s");
  };
  checkCounts(data.pointData, data.points.size(), "point");
  checkCounts(data.cellData, data.tets.size(), "cell");
  return data;
}

}  // namespace esim
