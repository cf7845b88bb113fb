"""Published figures of human play set beside the twin's shot statistics in twin_vs_real.md.

One record per (statistic, stroke) and source, each with what the source measured, on whom, and where it
was read. Only figures read in the source itself are here; a statistic without a record is shown as
NOT_FOUND. Rates in rev/s beside a source's rad/s are converted here (1 rev/s = 2 pi rad/s); speeds in
m/s beside a source's km/h likewise (1 m/s = 3.6 km/h). No source gives percentiles: the figures are
means with standard deviations, ranges or a record, and compare with the twin's percentiles as such.
"""

from typing import NamedTuple

NOT_FOUND = "no published figure found"


class Published(NamedTuple):
    statistic: str  # a key of pingpong.reports.twin_shots.STATISTICS
    stroke: str  # "all" or a stroke type of the twin's shots table
    figure: str  # the figure, as the source gives it (and converted where said)
    source: str  # authors, title, venue, year
    url: str  # where it was read


XIA_2020 = ("Xia R., Dai B., Fu W., Gu N., Wu Y.: Kinematic Comparisons of the Shakehand and Penhold Grips "
            "in Table Tennis Forehand and Backhand Strokes when Returning Topspin and Backspin Balls. "
            "Journal of Sports Science and Medicine 19, 637-644 (2020), Table 3")
XIA_2020_URL = "https://jssm.org/mobile/ShowTable.php?TableId=table003&jid=jssm-19-637.xml"
XIA_BACKHAND = ("backhand strokes of advanced male players returning topspin and backspin balls (Table 3 "
                "columns 'Backhand Topspin', 'Backhand Backspin'): ball forward velocity 16.13 +- 0.95 and "
                "14.63 +- 1.15 m/s (shakehand grip, n = 18, mean +- SD; penhold, n = 9: 15.11 +- 0.78 and "
                "13.71 +- 0.92 m/s)")
LIGHT_REFLECTION = ("Light reflection-based system for spin measurement of table tennis balls. Conference "
                    "abstract, HAL open archive hal-04557947 (authors and year not shown in the copy read)")
LIGHT_REFLECTION_URL = "https://hal.science/hal-04557947"
DELUMEAU_2025 = ("Delumeau T., Plot C., Le Carpentier E., Deschamps T., Mousseau P.: Relationship Between "
                 "Ball Speed and Spin in Elite Youth Table Tennis Players Using Optical Sensors. Applied "
                 "Sciences 15(11), 6350 (2025)")
DELUMEAU_2025_URL = "https://www.mdpi.com/2076-3417/15/11/6350"
RAHMANIAN_2023 = ("Rahmanian N., Gupta M., Soatto R., Nachuri S., Psenka M., Ma Y., Sastry S. S.: Role of "
                  "Uncertainty in Anticipatory Trajectory Prediction for a Ping-Pong Playing Robot. arXiv "
                  "2312.03024 (2023), the paper this project reproduces")
RAHMANIAN_2023_URL = "https://ar5iv.labs.arxiv.org/html/2312.03024 (and the LaTeX source in shared/paper/)"
SMASH_BLOG = ("How Fast Can You Smash? TableTennisCoaching.com blog, November 10, 2016 (author not named "
              "in the copy read)")
SMASH_BLOG_URL = "http://www.tabletenniscoaching.com/node/2534"
HODGES_1993 = ("Hodges L.: Table Tennis: Steps to Success. Human Kinetics, Champaign IL (1993), Step 11 "
               "'Lobbing: How to Return Smashes' (a coaching text, not a measurement)")
HODGES_1993_URL = "https://docslib.org/doc/8169164/step-11-lobbing-how-to-return-smashes"
HODGES_2019 = ("Hodges L.: Topspin Defense. Tip of the Week, TableTennisCoaching.com, September 16, 2019 (a "
               "coaching text, not a measurement)")
HODGES_2019_URL = "http://tabletenniscoaching.com/TipOfTheWeek?page=5"
HODGES_2013 = ("Hodges L.: Super Spinny Slow Loops. TableTennisCoaching.com, February 4, 2013 (a coaching "
               "text, not a measurement)")
HODGES_2013_URL = "http://www.tabletenniscoaching.com/node/1333"

PUBLISHED = (
    Published("speed", "all", XIA_BACKHAND, XIA_2020, XIA_2020_URL),
    Published("spin", "all",
              "one experienced senior player, strokes repeated with increasing spin: topspin forehands "
              "391.75-808.6 rad/s (62-129 rev/s), topspin backhands 569.8-769 rad/s (91-122 rev/s), "
              "serves 174-329.23 rad/s (28-52 rev/s); ranges", LIGHT_REFLECTION, LIGHT_REFLECTION_URL),
    Published("spin", "all",
              "'around 127 RPS for high spin' (quoting their ref. 9); over 9 elite youth players' 4 "
              "exercises, spin rises linearly with speed (r = 0.96)", DELUMEAU_2025, DELUMEAU_2025_URL),
    Published("bounce_depth", "all",
              "'most bounces occur for y in [-70, -10]' cm, i.e. 0.10-0.70 m from the net (the authors' "
              "own recorded play; no percentiles given)", RAHMANIAN_2023, RAHMANIAN_2023_URL),
    Published("bounce_in_band", "all", "'most bounces' lie within 0.10-0.70 m of the net (no share given)",
              RAHMANIAN_2023, RAHMANIAN_2023_URL),
    Published("speed", "drive", XIA_BACKHAND, XIA_2020, XIA_2020_URL),
    Published("spin", "loop",
              "topspin forehands 391.75-808.6 rad/s (62-129 rev/s), topspin backhands 569.8-769 rad/s "
              "(91-122 rev/s); one experienced senior player, ranges", LIGHT_REFLECTION,
              LIGHT_REFLECTION_URL),
    Published("speed", "smash",
              "record of 75.8 mph (122 km/h, 33.9 m/s) by D. Ovtcharov (radar gun), earlier record 69.9 "
              "mph (112.5 km/h, 31.25 m/s): maxima, not typical values", SMASH_BLOG, SMASH_BLOG_URL),
    Published("net_height", "fish",
              "topspin defence from off the table: 'the ball crosses the net perhaps one to three feet high "
              "[0.30-0.91 m], sometimes higher or lower', with topspin, landing deep", HODGES_2019,
              HODGES_2019_URL),
    Published("net_height", "lob",
              "'a good lob ... can go 15 feet [4.6 m] or more in the air, has lots of topspin or sidespin, "
              "and lands deep on the table (some players lob lower but with more spin)': the top of the arc, "
              "not its height at the net", HODGES_1993, HODGES_1993_URL),
    Published("net_height", "loop",
              "the slow, spinny loop: 'arc the ball a little higher than usual, making it go deep' (no "
              "height given)", HODGES_2013, HODGES_2013_URL),
)


def published_for(statistic: str, stroke: str) -> tuple[str, str]:
    """(figure, source) of every record for (statistic, stroke), each source with its URL, several joined
    by ' / '; (NOT_FOUND, '') when there is none."""
    found = [p for p in PUBLISHED if p.statistic == statistic and p.stroke == stroke]
    if not found:
        return NOT_FOUND, ""
    return " / ".join(p.figure for p in found), " / ".join(f"{p.source} <{p.url}>" for p in found)
