// Contact history of the optix granular step (docs/method.md, "The optix granular step"): K
// slots per sphere, indexed by the sphere's stable id (its index in input order), each an entry
// (partner's stable id or a wall, springs). A pair's contact is written by its owner only, the
// sphere whose ray reports it; where the owner changed since the last step (the state was
// re-sorted, or the proxy rule's choice moved with the distance), the contact is found in the
// partner's slots with its springs negated. Needs contact.cuh prepended. With MOCHI_LOAD_HISTORY
// (the Mindlin–Deresiewicz model) each entry has a load history beside it, in a buffer of its
// own (`loads`, of the same slots); without, that buffer is never read or written.

// Partner id of the low x wall; the six walls are MOCHI_FIRST_WALL + 2·axis + side (FIRST_WALL
// in src/particles/history.rs).
#define MOCHI_FIRST_WALL 0xFFFFFFFAu

// One contact as its holder keeps it. Keep in sync with HistoryEntry in
// src/particles/history.rs (7 words: the host uploads and reads its entries as they are).
struct MochiHistoryEntry {
    unsigned int partner;
    float tangential[3];
    float rolling[3];
};

// The load history of an entry (Mindlin–Deresiewicz). Keep in sync with LoadEntry in
// src/particles/history.rs (4 words).
struct MochiLoadEntry {
    float reversal[3];
    float normal;
};

// Slots of one history buffer: `count[id]` entries in use of sphere `id`'s `slots` from
// `entries + id·slots` on (and their load histories from `loads + id·slots` on, with
// MOCHI_LOAD_HISTORY).
struct MochiSlots {
    const unsigned int* count;
    const MochiHistoryEntry* entries;
    unsigned int slots;
    const MochiLoadEntry* loads;
};

// The springs of slot `at` (counted from the first sphere's) of `h`.
static __forceinline__ __device__ MochiSprings mochi_springs_of(const MochiSlots& h,
                                                                unsigned long long at) {
    const MochiHistoryEntry& e = h.entries[at];
    MochiSprings s;
    s.tangential = mochi_v3(e.tangential[0], e.tangential[1], e.tangential[2]);
    s.rolling = mochi_v3(e.rolling[0], e.rolling[1], e.rolling[2]);
#ifdef MOCHI_LOAD_HISTORY
    const MochiLoadEntry& l = h.loads[at];
    s.reversal = mochi_v3(l.reversal[0], l.reversal[1], l.reversal[2]);
    s.normal = l.normal;
#endif
    return s;
}

// Keeps the contact with `partner` and its springs `s` in slot `at` of `entries` (and its load
// history in `loads`, with MOCHI_LOAD_HISTORY).
static __forceinline__ __device__ void mochi_keep_entry(MochiHistoryEntry* entries,
                                                        MochiLoadEntry* loads,
                                                        unsigned long long at,
                                                        unsigned int partner, MochiSprings s) {
    MochiHistoryEntry e;
    e.partner = partner;
    e.tangential[0] = s.tangential.x;
    e.tangential[1] = s.tangential.y;
    e.tangential[2] = s.tangential.z;
    e.rolling[0] = s.rolling.x;
    e.rolling[1] = s.rolling.y;
    e.rolling[2] = s.rolling.z;
    entries[at] = e;
#ifdef MOCHI_LOAD_HISTORY
    MochiLoadEntry l;
    l.reversal[0] = s.reversal.x;
    l.reversal[1] = s.reversal.y;
    l.reversal[2] = s.reversal.z;
    l.normal = s.normal;
    loads[at] = l;
#endif
}

// Whether sphere `holder` kept a contact with `partner` in `h`; its springs into `out`.
static __forceinline__ __device__ bool mochi_find(const MochiSlots& h, unsigned int holder,
                                                  unsigned int partner, MochiSprings& out) {
    unsigned long long first = (unsigned long long)holder * h.slots;
    const MochiHistoryEntry* e = h.entries + first;
    unsigned int count = h.count[holder];
    for (unsigned int k = 0; k < count; ++k) {
        if (e[k].partner == partner) {
            out = mochi_springs_of(h, first + k);
            return true;
        }
    }
    return false;
}

// The first of sphere `holder`'s slots in `h` at or after `first` that holds a contact with
// `partner` (its springs into `out`), or its count where none does.
static __forceinline__ __device__ unsigned int mochi_find_from(const MochiSlots& h,
                                                               unsigned int holder,
                                                               unsigned int partner,
                                                               unsigned int first,
                                                               MochiSprings& out) {
    unsigned long long row = (unsigned long long)holder * h.slots;
    const MochiHistoryEntry* e = h.entries + row;
    unsigned int count = h.count[holder];
    for (unsigned int k = first; k < count; ++k) {
        if (e[k].partner == partner) {
            out = mochi_springs_of(h, row + k);
            return k;
        }
    }
    return count;
}

// Whether sphere `i` had a contact with sphere `j` (stable ids) at the last step, its springs
// into `out`: its own entry, else j's negated, else none (a new contact).
static __forceinline__ __device__ bool mochi_old_contact(const MochiSlots& h, unsigned int i,
                                                         unsigned int j, MochiSprings& out) {
    if (mochi_find(h, i, j, out)) {
        return true;
    }
    if (mochi_find(h, j, i, out)) {
        out = mochi_negated(out);
        return true;
    }
    out = mochi_no_springs();
    return false;
}
