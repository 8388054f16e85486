/* Authenticated frames (hil_auth.h): SHA-256, HMAC-SHA256 and the SecOC-like trailer. */
#include <string.h>

#include "hil_auth.h"

static const uint32_t K[64] = {
    0x428a2f98u, 0x71374491u, 0xb5c0fbcfu, 0xe9b5dba5u, 0x3956c25bu, 0x59f111f1u, 0x923f82a4u, 0xab1c5ed5u,
    0xd807aa98u, 0x12835b01u, 0x243185beu, 0x550c7dc3u, 0x72be5d74u, 0x80deb1feu, 0x9bdc06a7u, 0xc19bf174u,
    0xe49b69c1u, 0xefbe4786u, 0x0fc19dc6u, 0x240ca1ccu, 0x2de92c6fu, 0x4a7484aau, 0x5cb0a9dcu, 0x76f988dau,
    0x983e5152u, 0xa831c66du, 0xb00327c8u, 0xbf597fc7u, 0xc6e00bf3u, 0xd5a79147u, 0x06ca6351u, 0x14292967u,
    0x27b70a85u, 0x2e1b2138u, 0x4d2c6dfcu, 0x53380d13u, 0x650a7354u, 0x766a0abbu, 0x81c2c92eu, 0x92722c85u,
    0xa2bfe8a1u, 0xa81a664bu, 0xc24b8b70u, 0xc76c51a3u, 0xd192e819u, 0xd6990624u, 0xf40e3585u, 0x106aa070u,
    0x19a4c116u, 0x1e376c08u, 0x2748774cu, 0x34b0bcb5u, 0x391c0cb3u, 0x4ed8aa4au, 0x5b9cca4fu, 0x682e6ff3u,
    0x748f82eeu, 0x78a5636fu, 0x84c87814u, 0x8cc70208u, 0x90befffau, 0xa4506cebu, 0xbef9a3f7u, 0xc67178f2u};

static uint32_t rotr(uint32_t x, unsigned n)
{
    return (x >> n) | (x << (32u - n));
}

static void compress(uint32_t h[8], const uint8_t *p)
{
    uint32_t w[64];
    uint32_t a, b, c, d, e, f, g, hh;
    unsigned i;
    for (i = 0; i < 16u; i++) {
        w[i] = ((uint32_t)p[4u * i] << 24) | ((uint32_t)p[4u * i + 1u] << 16) | ((uint32_t)p[4u * i + 2u] << 8)
               | (uint32_t)p[4u * i + 3u];
    }
    for (i = 16; i < 64u; i++) {
        const uint32_t s0 = rotr(w[i - 15u], 7) ^ rotr(w[i - 15u], 18) ^ (w[i - 15u] >> 3);
        const uint32_t s1 = rotr(w[i - 2u], 17) ^ rotr(w[i - 2u], 19) ^ (w[i - 2u] >> 10);
        w[i] = w[i - 16u] + s0 + w[i - 7u] + s1;
    }
    a = h[0]; b = h[1]; c = h[2]; d = h[3]; e = h[4]; f = h[5]; g = h[6]; hh = h[7];
    for (i = 0; i < 64u; i++) {
        const uint32_t t1 = hh + (rotr(e, 6) ^ rotr(e, 11) ^ rotr(e, 25)) + ((e & f) ^ (~e & g)) + K[i] + w[i];
        const uint32_t t2 = (rotr(a, 2) ^ rotr(a, 13) ^ rotr(a, 22)) + ((a & b) ^ (a & c) ^ (b & c));
        hh = g; g = f; f = e; e = d + t1; d = c; c = b; b = a; a = t1 + t2;
    }
    h[0] += a; h[1] += b; h[2] += c; h[3] += d; h[4] += e; h[5] += f; h[6] += g; h[7] += hh;
}

void hil_sha256_init(hil_sha256_t *s)
{
    static const uint32_t H0[8] = {0x6a09e667u, 0xbb67ae85u, 0x3c6ef372u, 0xa54ff53au,
                                   0x510e527fu, 0x9b05688cu, 0x1f83d9abu, 0x5be0cd19u};
    memcpy(s->h, H0, sizeof H0);
    s->bytes = 0u;
    s->used = 0u;
}

void hil_sha256_update(hil_sha256_t *s, const uint8_t *data, size_t n)
{
    s->bytes += n;
    while (n > 0u) {
        size_t take = 64u - s->used;
        if (take > n) {
            take = n;
        }
        memcpy(s->buf + s->used, data, take);
        s->used += (uint32_t)take;
        data += take;
        n -= take;
        if (s->used == 64u) {
            compress(s->h, s->buf);
            s->used = 0u;
        }
    }
}

void hil_sha256_final(hil_sha256_t *s, uint8_t out[32])
{
    const uint64_t bits = s->bytes * 8u;
    unsigned i;
    s->buf[s->used++] = 0x80u;
    if (s->used > 56u) {
        memset(s->buf + s->used, 0, 64u - s->used);
        compress(s->h, s->buf);
        s->used = 0u;
    }
    memset(s->buf + s->used, 0, 56u - s->used);
    for (i = 0; i < 8u; i++) {
        s->buf[56u + i] = (uint8_t)(bits >> (56u - 8u * i));
    }
    compress(s->h, s->buf);
    for (i = 0; i < 8u; i++) {
        out[4u * i] = (uint8_t)(s->h[i] >> 24);
        out[4u * i + 1u] = (uint8_t)(s->h[i] >> 16);
        out[4u * i + 2u] = (uint8_t)(s->h[i] >> 8);
        out[4u * i + 3u] = (uint8_t)s->h[i];
    }
}

/* The inner and outer states of HMAC after the padded key blocks. */
static void hmac_states(const uint8_t *key, size_t key_n, hil_sha256_t *inner, hil_sha256_t *outer)
{
    uint8_t pad[64];
    unsigned i;
    memset(pad, 0, sizeof pad);
    memcpy(pad, key, key_n);
    for (i = 0; i < 64u; i++) {
        pad[i] ^= 0x36u;
    }
    hil_sha256_init(inner);
    hil_sha256_update(inner, pad, 64u);
    for (i = 0; i < 64u; i++) {
        pad[i] ^= (uint8_t)(0x36u ^ 0x5cu);
    }
    hil_sha256_init(outer);
    hil_sha256_update(outer, pad, 64u);
}

static void hmac_finish(const hil_sha256_t *outer, hil_sha256_t *inner, uint8_t out[32])
{
    hil_sha256_t o = *outer;
    uint8_t digest[32];
    hil_sha256_final(inner, digest);
    hil_sha256_update(&o, digest, sizeof digest);
    hil_sha256_final(&o, out);
}

void hil_hmac_sha256(const uint8_t *key, size_t key_n, const uint8_t *data, size_t n, uint8_t out[32])
{
    hil_sha256_t inner, outer;
    uint8_t hashed[32];
    if (key_n > 64u) { /* a key longer than a block is hashed first (RFC 2104) */
        hil_sha256_init(&inner);
        hil_sha256_update(&inner, key, key_n);
        hil_sha256_final(&inner, hashed);
        key = hashed;
        key_n = sizeof hashed;
    }
    hmac_states(key, key_n, &inner, &outer);
    hil_sha256_update(&inner, data, n);
    hmac_finish(&outer, &inner, out);
}

int hil_auth_init(hil_auth_t *a, const uint8_t *key, size_t key_n, int target_role)
{
    memset(a, 0, sizeof *a);
    if (key_n < HIL_AUTH_KEY_MIN || key_n > HIL_AUTH_KEY_MAX) {
        return -1;
    }
    hmac_states(key, key_n, &a->inner, &a->outer);
    a->tx_dir = target_role ? (uint8_t)HIL_AUTH_DIR_TARGET : (uint8_t)HIL_AUTH_DIR_HOST;
    a->rx_dir = target_role ? (uint8_t)HIL_AUTH_DIR_HOST : (uint8_t)HIL_AUTH_DIR_TARGET;
    a->on = 1;
    return 0;
}

void hil_auth_set_context(hil_auth_t *a, const uint8_t *ctx, size_t n)
{
    if (n > HIL_AUTH_CONTEXT_MAX) {
        n = HIL_AUTH_CONTEXT_MAX;
    }
    memcpy(a->ctx, ctx, n);
    a->ctx_n = (uint8_t)n;
    a->tx_fresh = 0u;
    a->rx_fresh = 0u;
}

void hil_auth_mac(const hil_auth_t *a, uint8_t dir, uint64_t fresh, const uint8_t *body, size_t n,
                  uint8_t mac[HIL_AUTH_MAC_SIZE])
{
    hil_sha256_t inner = a->inner;
    uint8_t head[1u + HIL_AUTH_CONTEXT_MAX + 8u];
    uint8_t out[32];
    size_t at = 0u;
    unsigned i;
    head[at++] = dir;
    memcpy(head + at, a->ctx, a->ctx_n);
    at += a->ctx_n;
    for (i = 0; i < 8u; i++) {
        head[at++] = (uint8_t)(fresh >> (8u * i));
    }
    hil_sha256_update(&inner, head, at);
    hil_sha256_update(&inner, body, n);
    hmac_finish(&a->outer, &inner, out);
    memcpy(mac, out, HIL_AUTH_MAC_SIZE);
}

void hil_auth_control_mac(const hil_auth_t *a, uint8_t dir, const uint8_t *d, size_t n,
                          uint8_t mac[HIL_AUTH_MAC_SIZE])
{
    hil_sha256_t inner = a->inner;
    uint8_t head[2];
    uint8_t out[32];
    head[0] = (uint8_t)HIL_AUTH_DIR_CONTROL;
    head[1] = dir;
    hil_sha256_update(&inner, head, sizeof head);
    hil_sha256_update(&inner, d, n);
    hmac_finish(&a->outer, &inner, out);
    memcpy(mac, out, HIL_AUTH_MAC_SIZE);
}

void hil_auth_seal(hil_auth_t *a, uint8_t *body, size_t n)
{
    const uint64_t fresh = ++a->tx_fresh;
    body[n] = (uint8_t)(fresh & 0xFFu);
    body[n + 1u] = (uint8_t)((fresh >> 8) & 0xFFu);
    hil_auth_mac(a, a->tx_dir, fresh, body, n, body + n + HIL_AUTH_FRESH_SIZE);
}

/* The full freshness whose low 16 bits are `low`: the nearest value at most 32767 ahead of `last`, else the one at
 * or behind it (a replay, or a wrap below zero: a value no sender used, so its MAC fails). */
static uint64_t full_fresh(uint64_t last, uint16_t low)
{
    const uint16_t ahead = (uint16_t)(low - (uint16_t)last);
    if (ahead != 0u && ahead < 0x8000u) {
        return last + ahead;
    }
    return last - (uint16_t)((uint16_t)last - low);
}

int hil_auth_open(hil_auth_t *a, const uint8_t *body, size_t n)
{
    uint8_t mac[HIL_AUTH_MAC_SIZE];
    uint64_t fresh;
    size_t m;
    uint8_t diff = 0u;
    unsigned i;
    if (n < HIL_AUTH_TRAILER) {
        return HIL_AUTH_FAILED;
    }
    m = n - HIL_AUTH_TRAILER;
    fresh = full_fresh(a->rx_fresh, (uint16_t)(body[m] | ((uint16_t)body[m + 1u] << 8)));
    hil_auth_mac(a, a->rx_dir, fresh, body, m, mac);
    for (i = 0; i < HIL_AUTH_MAC_SIZE; i++) { /* constant time */
        diff |= (uint8_t)(mac[i] ^ body[m + HIL_AUTH_FRESH_SIZE + i]);
    }
    if (diff != 0u) {
        return HIL_AUTH_FAILED;
    }
    if (fresh <= a->rx_fresh) {
        return HIL_AUTH_REPLAYED;
    }
    a->rx_fresh = fresh;
    return HIL_AUTH_OK;
}
