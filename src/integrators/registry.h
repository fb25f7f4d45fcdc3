/* registry.h — the one table of methods (integrators and drivers) and of the options they
 * declare, behind the public introspection functions of penumbra.h; and the step of pn_render
 * that turns a pn_options handle into the fields of a pn_render_job.
 *
 * Adding an option is one entry of the option table in registry.c plus the job field it fills
 * (render_job.h); adding a method is its own file(s), one entry of the method table, and the
 * bits of the option entries that apply to it. */
#ifndef PN_INTEGRATORS_REGISTRY_H
#define PN_INTEGRATORS_REGISTRY_H

#include "core/error.h"
#include "integrators/integrator.h"

/* How an option's value is stored in the pn_render_job. */
typedef enum pn_field_kind {
    PN_FIELD_U32,   /* uint32_t */
    PN_FIELD_INT,   /* int (CHOICE codes, signed integers) */
    PN_FIELD_F32,   /* float (a DOUBLE option rounded to float) */
    PN_FIELD_F64,   /* double */
    PN_FIELD_BOOL,  /* bool */
    PN_FIELD_LIST,  /* pn_job_list */
    PN_FIELD_STRING /* const char *, pointing into the pn_options (valid during pn_render) */
} pn_field_kind;

typedef struct pn_option_decl {
    pn_option_info info;
    uint32_t methods; /* bit i: applies to method i of the method table */
    size_t offset;    /* of the field in pn_render_job */
    pn_field_kind field;
    int choice_base; /* CHOICE: the code of choice k is choice_base + k (numeric names: the number) */
} pn_option_decl;

typedef struct pn_method_entry {
    pn_method_info info;
    const pn_integrator *integrator; /* NULL for drivers */
} pn_method_entry;

/* The table entries (NULL when out of range or unknown). */
const pn_method_entry *pn_registry_method(int index);
const pn_method_entry *pn_registry_method_kind(pn_method_role role, int kind);
/* The entry whose integrator is `integrator`, or NULL. */
const pn_method_entry *pn_registry_integrator_entry(const pn_integrator *integrator);

/* Checks settings->options, settings->spp and settings->threshold against the chosen methods,
 * and writes every option of the table into job (the set value, else the declared default).
 * Options of methods that are not chosen get their defaults too, so that job is complete. */
pn_status pn_registry_resolve(pn_context ctx, const pn_render_settings *settings, const pn_method_entry *integrator,
                              const pn_method_entry *driver, pn_render_job *job);

#endif
