// SPDX-License-Identifier: MIT
#include "lcmtypes/log/lcm_wire.hpp"

#include <array>
#include <cctype>
#include <stdexcept>

namespace pitmap::lcmlog {

// The .lcm texts, written into the build tree by lcmtypes/CMakeLists.txt.
extern const std::vector<std::string_view>& PitmapLcmTexts();

namespace {

// Bytes of a primitive LCM type; 0 for string (variable), -1 for a struct.
int PrimitiveSize(std::string_view type) {
    if (type == "int8_t" || type == "byte" || type == "boolean") return 1;
    if (type == "int16_t") return 2;
    if (type == "int32_t" || type == "float") return 4;
    if (type == "int64_t" || type == "double") return 8;
    if (type == "string") return 0;
    return -1;
}

bool IsInteger(std::string_view type) {
    return type == "int8_t" || type == "int16_t" || type == "int32_t" || type == "int64_t";
}

std::string StripComments(std::string_view text) {
    std::string out;
    out.reserve(text.size());
    for (std::size_t i = 0; i < text.size();) {
        if (text.compare(i, 2, "//") == 0) {
            while (i < text.size() && text[i] != '\n') ++i;
        } else if (text.compare(i, 2, "/*") == 0) {
            const std::size_t end = text.find("*/", i + 2);
            for (std::size_t k = i;
                 k < std::min(end == std::string_view::npos ? text.size() : end + 2, text.size());
                 ++k) {
                if (text[k] == '\n') out += '\n';
            }
            i = end == std::string_view::npos ? text.size() : end + 2;
        } else {
            out += text[i++];
        }
    }
    return out;
}

std::string Trim(std::string_view s) {
    std::size_t a = 0;
    std::size_t b = s.size();
    while (a < b && std::isspace(static_cast<unsigned char>(s[a]))) ++a;
    while (b > a && std::isspace(static_cast<unsigned char>(s[b - 1]))) --b;
    return std::string(s.substr(a, b - a));
}

std::string Unqualified(std::string type) {
    const std::size_t dot = type.rfind('.');
    return dot == std::string::npos ? type : type.substr(dot + 1);
}

// One member declaration ("int32_t range_counts[num_beams]"), without the ';'.
void ParseMember(const std::string& decl, Struct& s) {
    const std::size_t sp = decl.find_first_of(" \t\n");
    if (sp == std::string::npos) throw std::runtime_error("lcm: bad member '" + decl + "'");
    const std::string type = Unqualified(decl.substr(0, sp));
    std::string rest = decl.substr(sp);
    std::size_t start = 0;
    while (start <= rest.size()) {
        const std::size_t comma = rest.find(',', start);
        const std::string one = Trim(std::string_view(rest).substr(
            start, comma == std::string::npos ? std::string::npos : comma - start));
        Field f;
        f.type = type;
        const std::size_t bracket = one.find('[');
        f.name = Trim(std::string_view(one).substr(0, bracket));
        std::size_t b = bracket;
        while (b != std::string::npos) {
            const std::size_t close = one.find(']', b);
            if (close == std::string::npos)
                throw std::runtime_error("lcm: bad array '" + one + "'");
            const std::string dim = Trim(std::string_view(one).substr(b + 1, close - b - 1));
            Dim d;
            if (!dim.empty() && std::isdigit(static_cast<unsigned char>(dim[0]))) {
                d.size = std::stoll(dim);
            } else {
                d.ref = dim;
            }
            f.dims.push_back(d);
            b = one.find('[', close);
        }
        if (f.name.empty())
            throw std::runtime_error("lcm: member without a name in '" + decl + "'");
        s.fields.push_back(std::move(f));
        if (comma == std::string::npos) break;
        start = comma + 1;
    }
}

// Points every variable dimension at the member holding its size, which must be an earlier
// integer scalar of the same struct (the LCM specification's rule).
void ResolveSizes(Struct& s) {
    if (s.fields.size() > Struct::kMaxFields) {
        throw std::runtime_error("lcm: " + s.name + " has more than " +
                                 std::to_string(Struct::kMaxFields) + " members");
    }
    for (std::size_t k = 0; k < s.fields.size(); ++k) {
        for (Dim& d : s.fields[k].dims) {
            if (d.ref.empty()) continue;
            for (std::size_t j = 0; j < k; ++j) {
                const Field& f = s.fields[j];
                if (f.name == d.ref && f.dims.empty() && IsInteger(f.type)) {
                    d.ref_index = static_cast<int>(j);
                }
            }
            if (d.ref_index < 0) {
                throw std::runtime_error("lcm: " + s.name + "." + s.fields[k].name + ": size " +
                                         d.ref + " is no earlier integer member");
            }
        }
    }
}

class Walker {
public:
    Walker(const Schema& schema, const std::uint8_t* data, std::size_t size)
        : schema_(schema), p_(data), left_(size) {}

    std::size_t left() const { return left_; }

    // Empty on success, else the problem.
    std::string Struct(const pitmap::lcmlog::Struct& s, int depth) {
        if (depth > 16) return "structs nested too deeply";
        // Values of the integer members read so far, by member index (Parse checked that every
        // size member is an earlier integer scalar). On the stack: no allocation per message.
        std::array<std::int64_t, pitmap::lcmlog::Struct::kMaxFields> ints{};
        for (std::size_t k = 0; k < s.fields.size(); ++k) {
            const Field& f = s.fields[k];
            std::int64_t count = 1;
            for (const Dim& d : f.dims) {
                const std::int64_t n =
                    d.ref_index < 0 ? d.size : ints[static_cast<std::size_t>(d.ref_index)];
                if (n < 0) return s.name + "." + d.ref + " = " + std::to_string(n);
                // Every element takes at least one byte (strings four): a count larger than the
                // bytes left is impossible, whatever the element type.
                if (n > 0 && count > static_cast<std::int64_t>(left_) / n) {
                    return s.name + "." + f.name + ": " + std::to_string(n) +
                           " elements do not fit in " + std::to_string(left_) + " bytes";
                }
                count *= n;
            }
            const int size = PrimitiveSize(f.type);
            if (size > 0) {
                const std::uint64_t bytes = static_cast<std::uint64_t>(count) * size;
                if (bytes > left_) return s.name + "." + f.name + ": cut short";
                if (f.dims.empty() && IsInteger(f.type)) ints[k] = ReadInt(size);
                Skip(bytes);
            } else if (size == 0) {
                for (std::int64_t i = 0; i < count; ++i) {
                    if (left_ < 4) return s.name + "." + f.name + ": cut short";
                    const auto len = static_cast<std::int32_t>(ReadInt(4));
                    Skip(4);
                    if (len < 1 || static_cast<std::uint64_t>(len) > left_) {
                        return s.name + "." + f.name + ": string length " + std::to_string(len);
                    }
                    if (p_[len - 1] != 0) return s.name + "." + f.name + ": string without NUL";
                    Skip(static_cast<std::uint64_t>(len));
                }
            } else {
                const pitmap::lcmlog::Struct* nested = schema_.Find(f.type);
                if (nested == nullptr) return s.name + "." + f.name + ": unknown type " + f.type;
                for (std::int64_t i = 0; i < count; ++i) {
                    std::string problem = Struct(*nested, depth + 1);
                    if (!problem.empty()) return problem;
                }
            }
        }
        return {};
    }

private:
    std::int64_t ReadInt(int size) const {
        std::uint64_t v = 0;
        for (int i = 0; i < size; ++i) v = (v << 8) | p_[i];
        switch (size) {
            case 1:
                return static_cast<std::int8_t>(v);
            case 2:
                return static_cast<std::int16_t>(v);
            case 4:
                return static_cast<std::int32_t>(v);
            default:
                return static_cast<std::int64_t>(v);
        }
    }
    void Skip(std::uint64_t n) {
        p_ += n;
        left_ -= static_cast<std::size_t>(n);
    }

    const Schema& schema_;
    const std::uint8_t* p_;
    std::size_t left_;
};

}  // namespace

Schema Schema::Parse(const std::vector<std::string_view>& texts) {
    Schema schema;
    for (const std::string_view raw : texts) {
        const std::string text = StripComments(raw);
        std::size_t pos = 0;
        while ((pos = text.find("struct", pos)) != std::string::npos) {
            const bool word_start =
                pos == 0 || std::isspace(static_cast<unsigned char>(text[pos - 1]));
            const std::size_t open = text.find('{', pos);
            if (!word_start || open == std::string::npos) {
                pos += 6;
                continue;
            }
            Struct s;
            s.name = Trim(std::string_view(text).substr(pos + 6, open - pos - 6));
            const std::size_t close = text.find('}', open);
            if (close == std::string::npos) throw std::runtime_error("lcm: unterminated " + s.name);
            const std::string body = text.substr(open + 1, close - open - 1);
            std::size_t a = 0;
            while (a < body.size()) {
                std::size_t semi = body.find(';', a);
                if (semi == std::string::npos) semi = body.size();
                const std::string decl = Trim(std::string_view(body).substr(a, semi - a));
                a = semi + 1;
                if (decl.empty() || decl.rfind("const ", 0) == 0) continue;
                ParseMember(decl, s);
            }
            ResolveSizes(s);
            schema.structs_[s.name] = std::move(s);
            pos = close;
        }
    }
    return schema;
}

const Schema& Schema::Pitmap() {
    static const Schema schema = Parse(PitmapLcmTexts());
    return schema;
}

const Struct* Schema::Find(std::string_view name) const {
    const auto it = structs_.find(name);
    return it == structs_.end() ? nullptr : &it->second;
}

std::string Schema::Check(std::string_view type, const void* data, std::size_t size) const {
    const Struct* s = Find(type);
    if (s == nullptr) return "unknown type " + std::string(type);
    if (size < 8) return "shorter than a fingerprint";
    Walker w(*this, static_cast<const std::uint8_t*>(data) + 8, size - 8);
    std::string problem = w.Struct(*s, 0);
    if (!problem.empty()) return problem;
    if (w.left() != 0) return std::to_string(w.left()) + " bytes after the message";
    return {};
}

}  // namespace pitmap::lcmlog
