"""The report page's template (Jinja2, rendered with autoescape on by mavscope.report.html).

Kept as a Python string so the page ships with the module (no package data to find at run time). Only
the numbers of the drawings (computed in mavscope.report.geometry) and the document's strings, escaped,
are written into it.
"""

from mavscope.report.evidence import EVIDENCE
from mavscope.report.style import CSS, VERDICT_COLOURS

__all__ = ["TEMPLATE", "VERDICT_COLOURS"]

TEMPLATE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<meta name="generator" content="mavscope {{ doc.custody.tool.version }}">
<title>MAVLink incident report: {{ doc.inputs | map(attribute='file.name') | join(', ') }}</title>
<style>""" + CSS + """</style>
</head>
<body>
<header>
<h1>MAVLink incident report</h1>
<p class="muted">{{ doc.inputs | length }} capture(s): {{ doc.inputs | map(attribute='file.name') | join(', ') }}.
Made by mavscope {{ doc.custody.tool.version }} on {{ doc.custody.analysed_at }}.</p>
</header>
<nav><ul>
<li><a href="#custody">Chain of custody</a></li>
{% for i in doc.inputs %}{% set n = loop.index %}
<li><a href="#summary-{{ n }}">{{ i.file.name }}: what happened</a></li>
<li><a href="#findings-{{ n }}">{{ i.file.name }}: findings</a></li>
<li><a href="#timeline-{{ n }}">{{ i.file.name }}: timeline</a></li>
<li><a href="#map-{{ n }}">{{ i.file.name }}: map</a></li>
<li><a href="#plots-{{ n }}">{{ i.file.name }}: plots</a></li>
<li><a href="#missions-{{ n }}">{{ i.file.name }}: missions</a></li>
<li><a href="#params-{{ n }}">{{ i.file.name }}: parameters</a></li>
<li><a href="#files-{{ n }}">{{ i.file.name }}: files</a></li>
<li><a href="#links-{{ n }}">{{ i.file.name }}: links</a></li>
{% endfor %}
</ul></nav>

<section id="custody">
<h2>Chain of custody</h2>
<div class="scroll"><table class="wide" id="custody-inputs">
<thead><tr><th>capture</th><th class="num">size</th><th>SHA-256</th><th>kind</th><th>first frame</th>
<th>last frame</th><th class="num">frames</th><th>engine</th></tr></thead>
<tbody>
{% for i in doc.inputs %}
<tr>
<td data-label="capture"><code>{{ i.file.path }}</code></td>
<td class="num" data-label="size">{{ i.file.size | size }}</td>
<td data-label="SHA-256"><code class="sha256">{{ i.file.sha256 }}</code></td><td data-label="kind">{{ i.kind }}</td>
<td data-label="first frame">{{ i.span.start | iso }}</td><td data-label="last frame">{{ i.span.end | iso }}</td>
<td class="num" data-label="frames">{{ "{:,}".format(i.frames) }}</td><td data-label="engine">{{ i.engine }}</td></tr>
{% endfor %}
</tbody></table></div>
<table class="kv">
<tr>
<th>mavscope</th><td>{{ doc.custody.tool.version }} (Python {{ doc.custody.tool.python }}, pymavlink {{
doc.custody.tool.pymavlink }})</td></tr>
<tr><th>analysis ran</th><td>{{ doc.custody.analysed_at }}</td></tr>
<tr><th>command line</th><td><code>{{ doc.custody.command_line | join(' ') }}</code></td></tr>
<tr>
<th>keys given (names only)</th><td>{% set ns = namespace(any=false) %}{% for flag, names in
doc.custody['keys'].items() %}{% if names %}{% set ns.any = true %}{{ flag }}: {{ names | join(', ') }}; {% endif
%}{% endfor %}{% if not ns.any %}none{% endif %}{% if doc.custody.use_leaked_keys %}; --use-leaked-keys{% endif
%}{% if doc.custody.keyring %}; keyring <code>{{ doc.custody.keyring }}</code> ($MAVSCOPE_KEYRING){% endif %}</td></tr>
{% if doc.custody.params_file %}<tr>
<th>parameter file compared</th><td><code>{{ doc.custody.params_file.path }}</code> ({{ doc.custody.params_file.size
| size }}, SHA-256 <code>{{ doc.custody.params_file.sha256 }}</code>)</td></tr>{% endif %}
<tr><th>detection rules</th><td>{% for r in doc.custody.rules %}<code>{{ r.name }}</code>{{ ' (shipped pack)' if r.pack
}} SHA-256 <code class="hash">{{ r.sha256[:16] }}</code>...{{ '; ' if not loop.last
}}{% else %}none{% endfor %}</td></tr>
</table>
{% set tops = doc.custody.dialects | selectattr('included_by', 'none') | list %}
<p>Dialects: {% for d in tops %}<code>{{ d.name }}</code> (SHA-256 <code>{{ d.sha256[:16] }}</code>...){{
', ' if not loop.last }}{% endfor %}; with the files they include, {{ doc.custody.dialects | length }} files.</p>
<details><summary>Dialect files ({{ doc.custody.dialects | length }})</summary>
<div class="scroll"><table class="wide"><thead>
<tr>
<th>file</th>
<th>included by</th>
<th class="num">size</th>
<th>SHA-256</th></tr></thead>
<tbody>

{% for d in doc.custody.dialects %}<tr>
<td data-label="file"><code>{{ d.path }}</code></td>
<td data-label="included by">{{ d.included_by or '-' }}</td>
<td class="num" data-label="size">{{ d.size | size }}</td>
<td data-label="SHA-256"><code>{{ d.sha256 }}</code></td></tr>
{% endfor %}</tbody></table></div></details>
<p class="muted">Re-running the same command on the same files gives the same report but for the time the analysis ran.
Frame numbers are the capture's record numbers; each "show" command prints those frames in full.</p>
</section>

{% for i in doc.inputs %}{% set n = loop.index %}{% set v = views[loop.index0] %}
<article id="input-{{ n }}" class="input">
<section id="summary-{{ n }}">
<h2>{{ i.file.name }}: what happened</h2>
<div class="cards">
<div class="card"><span class="muted">span</span><b>{{ i.span.duration | duration }}</b>{{ i.span.start | iso }}</div>
<div class="card"><span class="muted">frames</span><b>{{ "{:,}".format(i.frames) }}</b>{{ i.stats.totals.links
}} links, {{ i.stats.totals.lost }} lost</div>
<div class="card"><span class="muted">vehicles / ground stations</span><b>{{ i.summary.vehicles | length }} / {{
i.summary.ground_stations | length }}</b></div>
<div class="card"><span class="muted">findings</span><b>{{ i.findings | length }}</b><span class="counts">{% for
sev, count in i.findings_by_severity.items() %}{% if count %}<span class="sev sev-{{ sev }}">{{ sev }} {{ count
}}</span> {% endif %}{% endfor %}</span></div>
</div>
{% set key = i.events.events | selectattr('kind', 'in', key_kinds) | list %}
<h3>Key events</h3>
{% if key %}<ul class="key-events" id="key-events-{{ n }}">
{% for e in key[:rows.key] %}<li><span class="mono">{{ e.time | iso }}</span> frame {{ e.frame }}: {{ e.text }}</li>
{% endfor %}</ul>
{% if key | length > rows.key %}<p class="more">{{ key | length - rows.key }} more arming, mode, failsafe, reboot and
signing events in the timeline below.</p>{% endif %}
{% else %}<p class="muted">No arming, mode change, failsafe, reboot or signing event.</p>{% endif %}
<h3>Vehicles</h3>
{% if i.summary.vehicles %}<div class="scroll"><table class="wide" id="vehicles-{{ n }}"><thead>
<tr>
<th>system</th>
<th>type</th>
<th>autopilot</th>
<th>firmware</th>
<th>last mode</th>
<th>armed</th>
<th>state</th></tr></thead>
<tbody>

{% for x in i.summary.vehicles[:rows.systems] %}<tr>
<td data-label="system">{{ x.sysid }}/{{ x.compid }}</td>
<td data-label="type">{{ x.type }}</td>
<td data-label="autopilot">{{ x.autopilot }}</td>
<td data-label="firmware">{% if x.firmware and x.firmware.get('flight') %}{{ x.firmware['flight'] }}{% if
x.firmware.get('git') %} git {{ x.firmware['git'] }}{% endif %}{% else %}<span class="muted">not sent</span>{% endif
%}</td>
<td data-label="last mode">{{ x.mode }}</td>
<td data-label="armed">{{ 'yes' if x.armed else 'no' }}</td>
<td data-label="state">{{ x.state }}</td></tr>
{% endfor %}</tbody></table></div>
{% if i.summary.vehicles | length > rows.systems %}<p class="more">{{ i.summary.vehicles | length - rows.systems }} more
vehicles: the JSON report (--json) lists them all.</p>{% endif %}
{% else %}<p class="muted">No HEARTBEAT of a vehicle.</p>{% endif %}
<h3>Ground stations and who commanded what</h3>
{% set gcs = i.summary.ground_stations %}
{% if gcs %}<p>Ground stations: {% for g in gcs[:rows.systems] %}{{ g.sysid }}/{{ g.compid }} ({{ g.type }}){{ ', ' if
not loop.last }}{% endfor %}{% if gcs | length > rows.systems %} and {{ gcs | length - rows.systems }} more{% endif
%}.</p>{% else
%}<p class="muted">No HEARTBEAT of a ground station.</p>{% endif %}
{% set cmds = i.summary.commanders %}
{% if cmds %}<details{% if cmds | length <= fold %} open{% endif %}><summary>{{ cmds | length
}} (sender, target, command) rows</summary>
<div class="scroll"><table class="wide" id="commanders-{{ n }}"><thead>
<tr>
<th>from</th>
<th>to</th>
<th>what</th>
<th class="num">times</th>
<th class="num">accepted</th>
<th class="num">first frame</th></tr></thead>
<tbody>

{% for c in cmds[:rows.commanders] %}<tr>
<td data-label="from">{{ c.from | addr }}</td>
<td data-label="to">{{ c.to | addr }}</td>
<td data-label="what">{{ c.what }}</td>
<td class="num" data-label="times">{{ c.count }}</td>
<td class="num" data-label="accepted">{{ c.accepted }}</td>
<td class="num" data-label="first frame">{{ c.first_frame }}</td></tr>
{% endfor %}</tbody></table></div>
{% if cmds | length > rows.commanders %}<p class="more">{{ cmds | length - rows.commanders }} more: <code>{{
v.more.events }}</code> lists every command.</p>{% endif %}
</details>{% else %}<p class="muted">No command, parameter set or mission upload in the capture.</p>{% endif %}
<h3>Signing per link</h3>
{% if i.summary.signing %}<div class="scroll"><table class="wide" id="signing-{{ n }}"><thead>
<tr>
<th>sender</th>
<th class="num">frames</th>
<th>verdict</th>
<th>signatures</th>
<th>endpoints</th></tr></thead>
<tbody>

{% for s in i.summary.signing[:rows.links] %}<tr>
<td data-label="sender">{{ s.sysid }}/{{ s.compid }}</td>
<td class="num" data-label="frames">{{ "{:,}".format(s.frames) }}</td>
<td data-label="verdict">{{ s.verdict }}</td>
<td data-label="signatures">{{ s.signature | counts }}</td>
<td data-label="endpoints">{{ s.endpoints[:4] | join(', ') }}{% if s.endpoints | length > 4 %} and {{ s.endpoints |
length - 4 }} more{% endif %}</td></tr>
{% endfor %}</tbody></table></div>
{% if i.summary.signing | length > rows.links %}<p class="more">{{ i.summary.signing | length - rows.links
}} more: <code>{{ v.more.links }}</code></p>{% endif %}
{% else %}<p class="muted">No MAVLink frames.</p>{% endif %}
<h3>Findings by severity</h3>
{% if i.findings %}<ul class="findings-summary">
{% for f in i.findings[:rows.summary_findings] %}<li><span class="sev sev-{{ f.severity }}">{{ f.severity
}}</span> <b>{{ f.code }}</b>{% if
f.get('rule') %} ({{ f['rule'] }}){% endif %}: {{ f.summary or f.message }}</li>
{% endfor %}</ul>
{% if i.findings | length > rows.summary_findings %}<p class="more">{{ i.findings | length - rows.summary_findings }}
more findings below.</p>{% endif %}
{% else %}<p>No findings.</p>{% endif %}
</section>

<section id="findings-{{ n }}">
<h2>{{ i.file.name }}: findings</h2>
<p class="muted">As <code>{{ v.more.findings }}</code> gives them.</p>
{% for f in i.findings[:rows.findings] %}<div class="finding" data-code="{{ f.code }}">
<h3><span class="sev sev-{{ f.severity }}">{{ f.severity }}</span> {{ f.code }}</h3>
<p>{{ f.message }}</p>
{% if f.explanation %}<p class="muted">{{ f.explanation }}</p>{% endif %}
{% if f.frames %}<p>Frames ({{ f.frames | length }}): <span class="mono">{{ f.frames[:rows.frames] | join(', ')
}}</span>{% if f.frames | length > rows.frames %} and {{ f.frames | length - rows.frames }} more ({{ v.more.findings
}} lists all){% endif %}<br>
Show them: <code>{{ f.show }}</code></p>{% endif %}
</div>
{% else %}<p>No findings.</p>{% endfor %}
{% if i.findings | length > rows.findings %}<p class="more">{{ i.findings | length - rows.findings }} more findings:
<code>{{ v.more.findings }}</code> lists them all.</p>{% endif %}
</section>

""" + EVIDENCE + """<footer><p class="muted">mavscope {{ doc.custody.tool.version }}; report schema {{ doc.schema }}
version {{ doc.schema_version }} (the JSON report holds the same facts).</p></footer>
<script>
window.addEventListener("beforeprint", function () {
  document.querySelectorAll("details").forEach(function (d) { d.open = true; });
});
</script>
</body>
</html>
"""
