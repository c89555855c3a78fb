// SPDX-License-Identifier: MIT
// The georeferenced view's points (georef::GeorefPoints, 38 bytes a sounding) moved to a file
// while a stage does not read them, and read back bit for bit when it needs them again: the
// stage's peak memory then leaves them out (decision 020). The file is this process's scratch
// (native byte order, removed when read back or when the SpilledPoints is destroyed), named
// .partial-* so that a killed run's leftover is removed with the other partial files
// (common/formats/replace_file.hpp).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "common/result.hpp"
#include "processor/georef/georef.hpp"

namespace pitmap::proc::io {

class SpilledPoints {
public:
    // Writes `points` to `path` and empties them (their memory returned); on an error (the
    // folder not writable, the disk full) `points` are left as they were and no file stays.
    static Expected<SpilledPoints> Spill(georef::GeorefPoints& points, const std::string& path);

    SpilledPoints(SpilledPoints&& other) noexcept;
    SpilledPoints& operator=(SpilledPoints&& other) noexcept;
    SpilledPoints(const SpilledPoints&) = delete;
    SpilledPoints& operator=(const SpilledPoints&) = delete;
    ~SpilledPoints();

    // Reads the points back into `points` (replacing what they hold) and removes the file. An
    // error (the file shorter or longer than what was written, or unreadable) names the file;
    // `points` are then empty. Only once.
    Status Restore(georef::GeorefPoints& points);

    // Soundings first .. first + count - 1 (count clipped at the end) read into `block`
    // (replacing what it holds), bit for bit the points Restore gives there; the file stays.
    // An error (the file gone, short or re-headed) names the file; `block` is then empty.
    Status ReadBlock(std::size_t first, std::size_t count, georef::GeorefPoints& block) const;

    // Keeps in the file only the soundings whose keep[j] is non-zero (keep: one per sounding
    // spilled), in their order, copying `block` soundings at a time through a second file that
    // replaces it. On an error the file is as it was.
    Status KeepOnly(const std::vector<char>& keep, std::size_t block);

    // Moves the soundings a block of `block` at a time: move(points, first) is given soundings
    // first .. first + count - 1 (every array as ReadBlock gives them) and may change their
    // positions (position_world) alone; the positions are written through a second file that
    // replaces this one, the other arrays copied as they are (decision 043). On an error (a
    // block's positions resized included) the file is as it was.
    Status MovePositions(std::size_t block,
                         const std::function<void(georef::GeorefPoints&, std::size_t)>& move);

    const std::string& path() const { return path_; }
    std::size_t size() const { return size_; }  // soundings spilled
    bool with_status() const { return with_status_; }

private:
    friend class SpillWriter;
    SpilledPoints(std::string path, std::size_t size, bool with_status)
        : path_(std::move(path)), size_(size), with_status_(with_status) {}
    std::string path_;  // empty once restored (or moved from)
    std::size_t size_ = 0;
    bool with_status_ = false;
};

// A view written to its file a block at a time as it is made (decision 033): the file a
// SpilledPoints then reads, byte for byte the one Spill writes of the blocks joined. At most
// `capacity` soundings (georef: the survey's beams) are appended; the arrays are laid out for
// that many while writing (the unwritten rest a hole of the file) and moved down to the
// soundings appended by Finish, which writes the header. Destroyed unfinished (an error, a
// cancelled georef), the file is removed.
class SpillWriter {
public:
    // Creates `path`; an error (the folder not writable) names it.
    static Expected<SpillWriter> Open(const std::string& path,
                                      std::size_t capacity,
                                      bool with_status);

    SpillWriter(SpillWriter&& other) noexcept;
    SpillWriter& operator=(SpillWriter&& other) noexcept;
    SpillWriter(const SpillWriter&) = delete;
    SpillWriter& operator=(const SpillWriter&) = delete;
    ~SpillWriter();

    // Appends `block`'s soundings (their arrays of one length; status filled exactly when the
    // writer is with_status). More than the capacity, or a write error, is an error naming the
    // file; the writer is then unusable.
    Status Append(const georef::GeorefPoints& block);
    // The arrays moved to where a file of size() soundings has them, the header written; the
    // file is then the SpilledPoints'.
    Expected<SpilledPoints> Finish();

    std::size_t size() const { return size_; }  // soundings appended
    const std::string& path() const { return path_; }

private:
    SpillWriter(std::string path, std::size_t capacity, bool with_status)
        : path_(std::move(path)), capacity_(capacity), with_status_(with_status) {}
    std::string path_;  // empty once finished (or moved from)
    std::size_t capacity_ = 0;
    std::size_t size_ = 0;
    bool with_status_ = false;
    bool failed_ = false;
};

// The file a stage spills the survey's view to in products folder `out_dir`.
std::string ViewSpillPath(const std::string& out_dir);
// A second name beside `current` (a spilled view's path) for a view made while that one is
// still on disk (the calibration's re-georeference): ViewSpillPath's and another, in turn.
std::string NextViewSpillPath(const std::string& out_dir, const std::string& current);

}  // namespace pitmap::proc::io
