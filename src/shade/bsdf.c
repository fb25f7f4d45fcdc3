/* bsdf.c — material evaluation: textures looked up, normals oriented, Lambert + Blinn–Phong. */
#include "shade/bsdf.h"

void pn_bsdf_at(const struct pn_scene_s *scene, const pn_hit *hit, vec3 wo, pn_bsdf *out) {
    const pn_material *m = (hit->material >= 0 && hit->material < scene->material_count)
                               ? &scene->materials[hit->material] : NULL;
    out->ng = hit->ng;
    out->ns = hit->ns;
    out->entering = v3_dot(hit->ng, wo) >= 0.0f;
    if (!out->entering) {
        out->ng = v3_neg(out->ng);
        out->ns = v3_neg(out->ns);
    }
    if (!m) {
        out->kind = PN_MATERIAL_LAMBERT_BLINN;
        out->kd = v3(0.5f, 0.5f, 0.5f);
        out->ks = v3(0, 0, 0);
        out->exponent = 1.0f;
        out->specular = v3(0, 0, 0);
        out->eta = 1.0f;
        return;
    }
    out->kind = m->kind;
    out->kd = pn_texture_eval(scene, m->kd, hit->u, hit->v);
    if (m->coated) out->kd = pn_coated_diffuse(out->kd, m->coat_transmission, m->coat_internal);
    out->ks = pn_texture_eval(scene, m->ks, hit->u, hit->v);
    out->exponent = m->exponent;
    out->specular = m->specular;
    out->eta = m->eta > 0.0f ? m->eta : 1.5f;
}

vec3 pn_bsdf_eval(const pn_bsdf *b, vec3 wo, vec3 wi) {
    float cos_i = v3_dot(b->ns, wi);
    if (cos_i <= 0.0f || v3_dot(b->ng, wi) <= 0.0f) return v3(0, 0, 0);
    vec3 f = v3_scale(b->kd, PN_INV_PI);
    if (!v3_is_zero(b->ks)) {
        vec3 h = v3_add(wo, wi);
        float hl = v3_length(h);
        if (hl > 0.0f) {
            float cos_h = fmaxf(0.0f, v3_dot(b->ns, v3_scale(h, 1.0f / hl)));
            float lobe = (b->exponent + 2.0f) * (0.5f * PN_INV_PI) * powf(cos_h, b->exponent);
            f = v3_madd(f, b->ks, lobe);
        }
    }
    return f;
}

vec3 pn_coated_diffuse(vec3 kd, float transmission, float internal) {
    return v3(kd.x * transmission / (1.0f - kd.x * internal), kd.y * transmission / (1.0f - kd.y * internal),
              kd.z * transmission / (1.0f - kd.z * internal));
}

bool pn_refract(vec3 wo, vec3 n, float eta, vec3 *wt) {
    float cos_i = v3_dot(n, wo);
    float sin2_i = fmaxf(0.0f, 1.0f - cos_i * cos_i);
    float sin2_t = sin2_i / (eta * eta);
    if (sin2_t >= 1.0f) return false;
    float cos_t = sqrtf(1.0f - sin2_t);
    *wt = v3_add(v3_scale(v3_neg(wo), 1.0f / eta), v3_scale(n, cos_i / eta - cos_t));
    return true;
}
