// A memory mapping owned by one object (mmap of a device buffer): unmapped
// when it goes out of scope, moved but never copied. `offset` skips to the
// data inside the mapping (a plane that starts inside a page).
#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>

#include <sys/mman.h>

namespace stemd::base {

class MappedMemory {
public:
    // `map` as mmap returned it, for `map_length` bytes (MAP_FAILED: none).
    MappedMemory(void* map, std::size_t map_length, std::size_t offset = 0) noexcept
        : map_(map), map_length_(map_length), offset_(offset)
    {
    }
    MappedMemory(MappedMemory&& other) noexcept
        : map_(std::exchange(other.map_, MAP_FAILED)), map_length_(other.map_length_), offset_(other.offset_)
    {
    }
    MappedMemory& operator=(MappedMemory&&) = delete;
    MappedMemory(const MappedMemory&) = delete;
    MappedMemory& operator=(const MappedMemory&) = delete;
    ~MappedMemory()
    {
        if (map_ != MAP_FAILED)
            ::munmap(map_, map_length_);
    }

    const std::uint8_t* bytes() const { return static_cast<const std::uint8_t*>(map_) + offset_; }
    std::size_t length() const { return map_length_ - offset_; }

private:
    void* map_;
    std::size_t map_length_;
    std::size_t offset_;
};

}  // namespace stemd::base
