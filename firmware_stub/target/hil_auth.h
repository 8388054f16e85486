/*
 * Authenticated frames of the HIL link in the spirit of AUTOSAR SecOC (docs/protocol.md, "Authenticated
 * frames"; src/pmsm_hil/protocol/links/auth.py is the same in Python): every frame body (header + payload) is followed by a
 * trailer of the freshness value's low 16 bits (u16 LE) and a MAC truncated to 32 bits, the first 4 bytes of
 * HMAC-SHA256(key, direction || context || freshness u64 LE || header || payload). `direction` is the sender's
 * role ('H' host, 'T' target), so a frame reflected back to its sender fails; `context` is the UDP session id
 * and the adopting end's nonce (u32 LE each, 8 bytes; empty on serial). Each direction counts its own freshness
 * from 1 (reset when a UDP session is agreed); the receiver keeps the full value of the last frame it accepted
 * and reads the 16 wire bits as the nearest value at most 32767 ahead of it: a frame whose MAC fails is
 * dropped (auth_failed), one whose MAC holds but whose freshness is not ahead is a replay (auth_replayed).
 *
 * SHA-256 (FIPS 180-4) and HMAC (RFC 2104) in C99 without dependencies or allocation; the key's inner and outer
 * padded blocks are hashed once (hil_auth_init), so a MAC of a frame up to 119 bytes costs two compressions
 * more for the inner hash and one for the outer. Python's hmac/hashlib are the reference (tests).
 */
#ifndef HIL_AUTH_H
#define HIL_AUTH_H

#include <stddef.h>
#include <stdint.h>

#define HIL_AUTH_KEY_MIN 16u  /* bytes of a key (128 bit) at least */
#define HIL_AUTH_KEY_MAX 64u  /* bytes of a key at most (one SHA-256 block: used as it is) */
#define HIL_AUTH_FRESH_SIZE 2u
#define HIL_AUTH_MAC_SIZE 4u
#define HIL_AUTH_TRAILER (HIL_AUTH_FRESH_SIZE + HIL_AUTH_MAC_SIZE)
#define HIL_AUTH_CONTEXT_MAX 8u
#define HIL_AUTH_DIR_HOST 0x48u   /* 'H': sent by the host */
#define HIL_AUTH_DIR_TARGET 0x54u /* 'T': sent by the target */
#define HIL_AUTH_DIR_CONTROL 0x43u /* 'C': prefixed to the direction of a UDP control datagram's MAC */

typedef struct {
    uint32_t h[8];
    uint64_t bytes;    /* message bytes hashed so far */
    uint8_t buf[64];
    uint32_t used;     /* bytes in buf */
} hil_sha256_t;

typedef struct {
    int32_t on;              /* 0: frames are not authenticated (no trailer) */
    hil_sha256_t inner;      /* SHA-256 state after key ^ ipad */
    hil_sha256_t outer;      /* SHA-256 state after key ^ opad */
    uint64_t tx_fresh;       /* freshness of the last frame sent (the next is one more) */
    uint64_t rx_fresh;       /* freshness of the last frame accepted (0: none yet) */
    uint8_t tx_dir;          /* HIL_AUTH_DIR_HOST or _TARGET: this end's role */
    uint8_t rx_dir;          /* the peer's */
    uint8_t ctx_n;           /* bytes of ctx in use */
    uint8_t ctx[HIL_AUTH_CONTEXT_MAX];
} hil_auth_t;

void hil_sha256_init(hil_sha256_t *s);
void hil_sha256_update(hil_sha256_t *s, const uint8_t *data, size_t n);
void hil_sha256_final(hil_sha256_t *s, uint8_t out[32]);
/* HMAC-SHA256 of n bytes (RFC 2104: a key longer than 64 bytes is hashed first). */
void hil_hmac_sha256(const uint8_t *key, size_t key_n, const uint8_t *data, size_t n, uint8_t out[32]);

/* Authentication on with `key` (HIL_AUTH_KEY_MIN..MAX bytes) for an end of role `target_role` (1 target, 0 host),
 * freshness from the start and no context: 0, or -1 for a key of another length (then off). */
int hil_auth_init(hil_auth_t *a, const uint8_t *key, size_t key_n, int target_role);

/* Context of the frames' MACs from now on (the UDP session and nonce; n <= HIL_AUTH_CONTEXT_MAX); the freshness
 * of both directions starts again. */
void hil_auth_set_context(hil_auth_t *a, const uint8_t *ctx, size_t n);

/* The 4-byte MAC of a frame body of n bytes sent in direction `dir` with freshness `fresh`. */
void hil_auth_mac(const hil_auth_t *a, uint8_t dir, uint64_t fresh, const uint8_t *body, size_t n,
                  uint8_t mac[HIL_AUTH_MAC_SIZE]);

/* The 4-byte MAC of a UDP control datagram of n bytes sent in direction `dir` (no freshness, no context). */
void hil_auth_control_mac(const hil_auth_t *a, uint8_t dir, const uint8_t *d, size_t n,
                          uint8_t mac[HIL_AUTH_MAC_SIZE]);

/* Append the trailer of the next frame to the body of n bytes at body[n..n+5] (the caller has the room). */
void hil_auth_seal(hil_auth_t *a, uint8_t *body, size_t n);

#define HIL_AUTH_OK 1
#define HIL_AUTH_FAILED 0
#define HIL_AUTH_REPLAYED (-1)
/* A received body of n bytes ending in its trailer: HIL_AUTH_OK (its freshness now the last accepted),
 * HIL_AUTH_FAILED (too short, or the MAC does not match: a spoofed, altered or foreign-key frame) or
 * HIL_AUTH_REPLAYED (the MAC holds but the freshness is not ahead of the last frame accepted). */
int hil_auth_open(hil_auth_t *a, const uint8_t *body, size_t n);

#endif
